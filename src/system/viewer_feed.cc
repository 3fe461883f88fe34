#include "viewer_feed.h"

#include <algorithm>
#include <unordered_map>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "ltlo/core/camera.h"
#include "ltlo/core/undistorter.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/loop/loop_closer.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/frame.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/system/run_recorder.h"
#include "ltlo/system/system.h"

namespace ltlo::system {

viewer::ViewerOutputs ViewerFeed::outputs(const SystemOptions& options) {
  viewer::ViewerOutputs viewer_outputs;
  viewer_outputs.video_path = options.viewer_video_path;
  viewer_outputs.png_dir = options.viewer_png_dir;
  viewer_outputs.http_port = options.viewer_http_port;
  viewer_outputs.http_bind = options.viewer_http_bind;
  viewer_outputs.pose_stream = options.viewer_pose_stream;
  return viewer_outputs;
}

ViewerFeed::ViewerFeed(const ViewerOptions& options, const viewer::ViewerOutputs& outputs,
                       viewer::Viewer::MapSource map_source, const loop::LoopCloser& closer,
                       const PinholeCamera& camera, const Undistorter& undistorter, TimingStats& timing)
    : viewer_(std::make_unique<viewer::Viewer>(options, outputs, std::move(map_source))),
      closer_(closer),
      camera_(camera),
      undistorter_(undistorter),
      timing_(timing) {}

void ViewerFeed::post(int index, const io::RgbdImuFrame& input, const map::Frame& frame,
                      tracking::TrackingState state, const RecordedFrame& recorded) {
  viewer_->postPose(index, input.t_s, frame.T_w_c(), recorded.tracked, recorded.map.value);
  const int events = closer_.numLoops() + closer_.numMerges();
  if (events != events_seen_) {
    events_seen_ = events;
    viewer_->notifyLoop();
  }
  if (!viewer_->due(input.t_s)) return;
  ScopedTimer timer(timing_, "tracking.viewer_post");
  viewer_->post(pictureOf(index, input, frame, state, recorded));
}

viewer::ViewerFrame ViewerFeed::pictureOf(int frame_index, const io::RgbdImuFrame& input, const map::Frame& frame,
                                          tracking::TrackingState state, const RecordedFrame& recorded) {
  // A frame the viewer is done with: copying into its buffers allocates nothing.
  viewer::ViewerFrame view = viewer_->recycledFrame();
  view.index = frame_index;
  view.t_s = input.t_s;
  input.color_bgr.copyTo(view.color_bgr);
  view.dynamic_mask =
      frame.segmentation().dynamicMask(frame.staticThreshold(), camera_.height() / 4, camera_.width() / 4);
  // The picture shows the raw image: with a distorting lens the mask (ideal grid) and the keypoints
  // (ideal pixels) are taken back through the lens, as the segmentation writer does for its masks.
  if (undistorter_.active() && !view.dynamic_mask.empty()) {
    if (raw_to_ideal_.size() != view.dynamic_mask.size()) {
      const int scale = std::max(1, camera_.width() / view.dynamic_mask.cols);
      cv::resize(undistorter_.rawToIdealMap(scale), raw_to_ideal_, view.dynamic_mask.size(), 0.0, 0.0,
                 cv::INTER_AREA);
    }
    cv::Mat raw_mask;
    cv::remap(view.dynamic_mask, raw_mask, raw_to_ideal_, cv::noArray(), cv::INTER_NEAREST,
              cv::BORDER_REPLICATE);
    view.dynamic_mask = raw_mask;
  }
  const std::vector<features::Keypoint>& keypoints = frame.keypoints();
  view.keypoints.clear();
  view.keypoints.reserve(keypoints.size());
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    viewer::ViewerKeypoint kp;
    Vec2 u(keypoints[i].x_px, keypoints[i].y_px);
    if (undistorter_.active()) u = undistorter_.model().distortPixel(u);
    kp.u = static_cast<float>(u.x());
    kp.v = static_cast<float>(u.y());
    const int index = static_cast<int>(i);
    if (!frame.isStatic(index)) {
      kp.kind = viewer::KeypointClass::kDynamic;
    } else if (i < frame.map_points.size() && frame.map_points[i].valid() &&
               !(i < frame.outliers.size() && frame.outliers[i])) {
      kp.kind = viewer::KeypointClass::kTracked;
    }
    view.keypoints.push_back(kp);
  }
  view.has_pose = true;
  view.T_w_c = frame.T_w_c();
  view.map = recorded.map.value;
  view.state = tracking::trackingStateName(state);
  view.imu_carried = recorded.carried;
  view.tracked = recorded.tracked;
  return view;
}

void ViewerFeed::stop() { viewer_->stop(); }

void ViewerFeed::addCounts(RunReport& report) const {
  const viewer::ViewerCounts viewer = viewer_->counts();
  report.viewer_on = true;
  report.viewer_rendered = viewer.rendered;
  report.viewer_dropped = viewer.dropped;
  report.viewer_video_frames = viewer.video_frames;
  report.viewer_video_held = viewer.video_held;
  report.viewer_png_frames = viewer.png_frames;
  report.viewer_http_frames = viewer.http_frames;
  report.viewer_poses = viewer.poses;
}

viewer::ViewerMap viewerMapOf(map::Atlas& atlas, const loop::LoopCloser& closer, const RunRecorder& recorder,
                              std::uint64_t map_id) {
  viewer::ViewerMap view;
  const map::MapId resolved = atlas.resolve(map::MapId(map_id));
  view.map = resolved.value;
  const std::vector<map::MapId> map_ids = atlas.mapIds();
  view.maps = static_cast<int>(map_ids.size());
  for (const map::MapId id : map_ids) {
    if (const map::Map* map = atlas.map(id)) view.keyframes_all_maps += static_cast<int>(map->numKeyFrames());
  }
  view.loops = closer.numLoops();
  view.merges = closer.numMerges();
  map::Map* map = atlas.map(resolved);
  if (map == nullptr) return view;
  std::unordered_map<std::uint64_t, int> index_of;
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;
  for (const std::shared_ptr<map::KeyFrame>& kf : map->keyFrames()) {
    if (kf->isBad()) continue;
    index_of[kf->id().value] = static_cast<int>(keyframes.size());
    keyframes.push_back(kf);
    view.keyframes_T_w_c.push_back(kf->T_w_c());
  }
  for (std::size_t a = 0; a < keyframes.size(); ++a) {
    for (const map::KeyFrameId other : keyframes[a]->bestCovisibles(4)) {
      const auto found = index_of.find(other.value);
      if (found != index_of.end() && found->second != static_cast<int>(a)) {
        view.covisibility.emplace_back(static_cast<int>(a), found->second);
      }
    }
    for (const map::KeyFrameId other : keyframes[a]->loopEdges()) {
      const auto found = index_of.find(other.value);
      if (found != index_of.end() && found->second > static_cast<int>(a)) {
        view.loop_edges.emplace_back(static_cast<int>(a), found->second);
      }
    }
  }
  for (const std::shared_ptr<map::MapPoint>& point : map->mapPoints()) {
    if (point->isBad()) continue;
    view.points_w.push_back(point->p_w().cast<float>());
    view.beta.push_back(static_cast<float>(point->beta()));
  }
  view.trajectory_w = recorder.framePositionsInMap(resolved);
  return view;
}

}  // namespace ltlo::system
