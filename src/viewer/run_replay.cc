#include "ltlo/viewer/run_replay.h"

#include <cmath>
#include <set>
#include <utility>

#include <opencv2/core.hpp>

namespace ltlo::viewer {

RunReplay::RunReplay(RunRecording recording, double pose_tolerance_s)
    : recording_(std::move(recording)), pose_tolerance_s_(pose_tolerance_s) {
  map_.points_w.reserve(recording_.points.size());
  map_.beta.reserve(recording_.points.size());
  for (const ReplayPoint& point : recording_.points) {
    map_.points_w.push_back(point.p_w);
    map_.beta.push_back(point.beta);
  }
  map_.trajectory_w.reserve(recording_.trajectory.size());
  map_.keyframes_T_w_c.reserve(recording_.keyframes.size());
}

ViewerState RunReplay::state(int index, double t_s, const cv::Mat& color_bgr, const cv::Mat& dynamic_mask) {
  ViewerState state;
  state.replay = true;
  ViewerFrame& frame = state.frame;
  frame.index = index;
  frame.t_s = t_s;
  frame.color_bgr = color_bgr;
  frame.dynamic_mask = dynamic_mask;
  frame.state = "no pose";

  // Poses stamped before this frame belong to frames not replayed (e.g. a --first beyond them):
  // they still extend the trajectory drawn so far.
  const io::Trajectory& trajectory = recording_.trajectory;
  while (next_pose_ < trajectory.size() && trajectory[next_pose_].t_s < t_s - pose_tolerance_s_) {
    map_.trajectory_w.push_back(trajectory[next_pose_].T_w_x.translation().cast<float>());
    ++next_pose_;
  }
  if (next_pose_ < trajectory.size() && std::abs(trajectory[next_pose_].t_s - t_s) <= pose_tolerance_s_) {
    frame.has_pose = true;
    frame.tracked = true;
    frame.T_w_c = trajectory[next_pose_].T_w_x;
    frame.state = "replay";
    map_.trajectory_w.push_back(frame.T_w_c.translation().cast<float>());
    ++next_pose_;
    ++frames_with_pose_;
  }

  std::set<std::uint64_t> maps;
  while (next_keyframe_ < recording_.keyframes.size() &&
         recording_.keyframes[next_keyframe_].t_s <= t_s + pose_tolerance_s_) {
    map_.keyframes_T_w_c.push_back(recording_.keyframes[next_keyframe_].T_w_c);
    ++next_keyframe_;
  }
  for (std::size_t k = 0; k < next_keyframe_; ++k) maps.insert(recording_.keyframes[k].map);
  if (next_keyframe_ > 0) frame.map = recording_.keyframes[next_keyframe_ - 1].map;
  map_.map = frame.map;
  map_.keyframes_all_maps = static_cast<int>(next_keyframe_);
  map_.maps = static_cast<int>(maps.size());

  state.map = map_;
  if (!dynamic_mask.empty()) {
    state.dynamic_share = static_cast<double>(cv::countNonZero(dynamic_mask)) / static_cast<double>(dynamic_mask.total());
  }
  return state;
}

}  // namespace ltlo::viewer
