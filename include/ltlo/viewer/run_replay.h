#pragma once
/// Replay of a finished run in the live viewer's picture (issue 30, `view --run`): what a run
/// wrote (trajectory.txt or trajectory_online.txt, keyframes.txt, static_map.ply, segmentation/)
/// turned back into one ViewerState per input frame, so the same ViewerRenderer draws it.
///
/// What a run's files do not hold is not invented: the picture has no keypoints (the run does not
/// write them), no covisibility or loop edges, and no loop or merge counts (the status line then
/// leaves them out). The map panel shows the run's final static map (every point of
/// static_map.ply from the first frame on), the keyframes made up to the frame's time, and the
/// trajectory up to it; poses are the run's final ones (or the online ones).
#include <cstdint>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/io/trajectory_io.h"
#include "ltlo/viewer/viewer_state.h"

namespace ltlo::viewer {

struct ReplayKeyFrame {
  double t_s = 0.0;
  SE3 T_w_c;
  std::uint64_t map = 0;
};

struct ReplayPoint {
  Eigen::Vector3f p_w = Eigen::Vector3f::Zero();
  float beta = 1.0f;
};

/// A run as its files hold it; keyframes and trajectory by time.
struct RunRecording {
  io::Trajectory trajectory;  ///< T_w_c of every frame with a pose
  std::vector<ReplayKeyFrame> keyframes;
  std::vector<ReplayPoint> points;
};

/// Builds the states of one run in frame order. Not thread-safe; frames are given in time order
/// (the trajectory and keyframe cursors only move forward).
class RunReplay {
 public:
  /// `pose_tolerance_s`: a frame takes the trajectory's pose stamped within it (the run writes
  /// the frame's own timestamp, so 1e-4 s is plenty).
  explicit RunReplay(RunRecording recording, double pose_tolerance_s = 1e-4);

  /// The state of input frame `index` at time `t_s` with its colour image and the run's mask
  /// (empty: none). The image is referenced, not copied.
  ViewerState state(int index, double t_s, const cv::Mat& color_bgr, const cv::Mat& dynamic_mask);

  /// Frames given to state() that found a pose in the trajectory.
  int framesWithPose() const { return frames_with_pose_; }

 private:
  RunRecording recording_;
  double pose_tolerance_s_;
  std::size_t next_pose_ = 0;      ///< first trajectory pose not yet drawn
  std::size_t next_keyframe_ = 0;  ///< first keyframe not yet made
  ViewerMap map_;                  ///< grows with the frames
  int frames_with_pose_ = 0;
};

}  // namespace ltlo::viewer
