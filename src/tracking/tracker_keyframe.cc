// Tracker, part 5: the keyframe decision and the keyframe's creation (matches become observations,
// new close map points), and the keyframe a lost frame places at its IMU-predicted pose.
#include <algorithm>
#include <array>
#include <limits>

#include "bow/vocabulary.h"
#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "ltlo/tracking/tracker.h"
#include "tracker_util.h"

namespace ltlo::tracking {

using detail::clearMatches;
using detail::isMatched;

KeyFrameDecision Tracker::decideKeyFrame() const {
  KeyFrameDecision decision;
  if (options_.tracking.localisation_only) return decision;  // the loaded map is not changed
  if (state_ != TrackingState::kOk || !last_frame_) return decision;
  if (frames_since_keyframe_ < options_.min_frames_between_keyframes) return decision;
  if (still_ && options_.tracking.zupt_no_keyframes) return decision;  // at rest (issue 32)
  const KeyFrameOptions& kf = options_.keyframe;
  // Before the IMU initialisation the interval shrinks to ImuInit.MinTime / (MinKeyFrames - 1), so
  // the map can initialise the IMU as soon as MinTime of motion is covered.
  double max_interval_s = kf.max_interval_s;
  if ((!imu_initialised_ || early_keyframes_after_init_) && last_frame_->imu_from_last_frame &&
      options_.imu_init_keyframe_interval_s > 0.0) {
    max_interval_s = std::min(max_interval_s, options_.imu_init_keyframe_interval_s);
  }
  const double since_keyframe_s = last_frame_->t_s() - last_keyframe_t_s_;
  decision.interval = since_keyframe_s >= max_interval_s;
  decision.low_overlap = stats_.overlap < kf.max_overlap;
  // (The tolerance lets three 1/30 s frame steps count as 0.1 s.)
  constexpr double kTimeTolerance_s = 1e-6;
  decision.weak = stats_.inliers < kf.min_tracked_points && since_keyframe_s >= kf.weak_min_interval_s - kTimeTolerance_s;
  // A keyframe needs enough inliers to be anchored in the map. When tracking resumes after a loss,
  // a frame tracked with the inertial optimisation is anchored by its IMU link too and needs fewer:
  // the view is then mostly unmapped, and without a keyframe its few matches run out and tracking
  // is lost again. Elsewhere (e.g. beside an occluder) such weak keyframes would crowd the local
  // window, so the vision-only rule holds.
  const int anchor_inliers =
      stats_.inertial_link != 0 && resumed_without_keyframe_ ? kf.min_inliers_inertial : kf.min_inliers;
  decision.anchored = stats_.inliers >= anchor_inliers;
  decision.need = (decision.interval || decision.low_overlap || decision.weak) && decision.anchored;
  // Revisits: a view the map already holds gains nothing from a keyframe but one more observer of
  // the same points (local BA's fixed set, the culling and the loop closer's work all grow with
  // them); keyframe culling would remove it as redundant. Not after a loss, whose keyframe
  // re-anchors the IMU chain, nor before the IMU initialisation, which needs its keyframes.
  const bool imu_waits = !imu_initialised_ && last_frame_->imu_from_last_frame;
  if (decision.need && kf.revisit_max_interval_s > 0.0 && since_keyframe_s < kf.revisit_max_interval_s &&
      !resumed_without_keyframe_ && !imu_waits) {
    decision.view = mappedView();
    if (decision.view.mappedShare() >= kf.revisit_mapped_share && decision.view.newShare() <= kf.revisit_max_new_share) {
      decision.deferred_on_revisit = true;
      decision.need = false;
    }
  }
  return decision;
}

MappedView Tracker::mappedView() const {
  MappedView view;
  if (!last_frame_) return view;
  const map::Frame& frame = *last_frame_;
  const map::Map& active = atlas_.activeMap();
  const int min_observers = options_.keyframe.revisit_min_observers;
  // A coarse grid over the image: a cell with static features but no pose inlier is a part of the
  // view the map does not hold (8 x 6 cells: 80 px at VGA, about the spacing of 1000 features).
  constexpr int kGridColumns = 8;
  constexpr int kGridRows = 6;
  std::array<int, kGridColumns * kGridRows> static_in_cell{};
  std::array<bool, kGridColumns * kGridRows> inlier_in_cell{};
  const double column_scale = kGridColumns / static_cast<double>(std::max(1, frame.camera().width()));
  const double row_scale = kGridRows / static_cast<double>(std::max(1, frame.camera().height()));
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    const features::Keypoint& kp = frame.keypoints()[static_cast<std::size_t>(i)];
    const int column = std::clamp(static_cast<int>(kp.x_px * column_scale), 0, kGridColumns - 1);
    const int row = std::clamp(static_cast<int>(kp.y_px * row_scale), 0, kGridRows - 1);
    const auto cell = static_cast<std::size_t>(row * kGridColumns + column);
    if (frame.isStatic(i) && frame.depth_m(i) > 0.0f) {
      ++view.static_with_depth;
      ++static_in_cell[cell];
    }
    if (!isMatched(frame, i)) continue;
    inlier_in_cell[cell] = true;
    ++view.inliers;
    const auto point = active.mapPoint(frame.map_points[static_cast<std::size_t>(i)]);
    if (point && !point->isBad() && point->numObservations() >= min_observers) ++view.mapped_inliers;
  }
  for (std::size_t cell = 0; cell < static_in_cell.size(); ++cell) {
    if (!inlier_in_cell[cell]) view.unmatched += static_in_cell[cell];
  }
  return view;
}

std::shared_ptr<map::KeyFrame> Tracker::createKeyFrame() {
  LTLO_ASSERT(last_frame_.has_value(), "createKeyFrame() before any tracked frame");
  map::Map& active = activeMap();
  map::Frame& frame = *last_frame_;
  // The IMU since the last keyframe is this keyframe's link, unless it was re-anchored while lost.
  std::optional<imu::Preintegrated> imu_link;
  if (imu_since_keyframe_ && !imu_chain_broken_) imu_link = *imu_since_keyframe_;
  if (imu_link) frame.imu_from_last_keyframe = imu_link;
  // Keyframes need their BoW for the database (relocalisation, loops, merges).
  if (vocabulary_ != nullptr && !frame.hasBow()) frame.computeBow(*vocabulary_);
  const std::shared_ptr<map::KeyFrame> kf = active.createKeyFrame(frame);
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (!frame.map_points[k].valid()) continue;
    if (frame.outliers[k]) {
      frame.map_points[k] = map::MapPointId();
      frame.outliers[k] = false;
      continue;
    }
    const auto point = active.mapPoint(frame.map_points[k]);
    if (!point || !active.addObservation(*kf, i, *point)) {
      frame.map_points[k] = map::MapPointId();
      continue;
    }
    active.updateNormalAndDistances(*point);
    active.updateDescriptor(*point);
  }
  const int created = addNewMapPoints(*kf, frame);
  if (last_kf_.valid()) {
    kf->setPreviousKeyFrame(last_kf_);
    if (const auto previous = active.keyFrame(last_kf_)) previous->setNextKeyFrame(kf->id());
    kf->setImuFromPrevious(std::move(imu_link));
  }
  active.updateConnections(*kf);  // after the chain link: it is the parent of last resort
  imu_since_keyframe_.reset();
  imu_chain_broken_ = false;
  link_to_keyframe_ = true;
  last_kf_ = kf->id();
  last_kf_ptr_ = kf;
  last_kf_T_w_b_seen_ = kf->T_w_b();
  last_kf_v_w_b_seen_ = kf->v_w_b();
  // Its velocity is an inertial estimate when the frame's state came from the IMU (the
  // pose-inertial optimisation or, lost, the IMU prediction); else local mapping will set it.
  last_kf_inertial_ = imu_initialised_ && frame_information_.valid;
  last_kf_bias_seen_ = kf->bias();
  reference_kf_ = kf->id();
  reference_kf_ptr_ = kf;
  frame.reference_keyframe = kf->id();
  last_keyframe_t_s_ = frame.t_s();
  frames_since_keyframe_ = 0;
  resumed_without_keyframe_ = false;
  ++num_keyframes_;
  log::debug("keyframe ", kf->id(), " at t = ", frame.t_s(), " s: ", kf->numObservations(), " points (", created,
             " new)");
  if (local_mapping_) local_mapping_(active, kf);
  return kf;
}

int Tracker::addNewMapPoints(map::KeyFrame& kf, map::Frame& frame) {
  map::Map& active = activeMap();
  std::vector<std::pair<float, int>> by_depth;
  for (const int i : frame.staticKeypoints()) {
    const float depth = frame.depth_m(i);
    if (depth > 0.0f && !frame.map_points[static_cast<std::size_t>(i)].valid()) by_depth.emplace_back(depth, i);
  }
  std::sort(by_depth.begin(), by_depth.end());
  const SE3 T_w_c = frame.T_w_c();
  int created = 0;
  for (const auto& [depth, i] : by_depth) {
    if (depth > options_.close_depth_m && created >= options_.min_new_points) break;
    const auto point = active.createMapPoint(T_w_c * frame.p_c(i), kf.id());
    if (!active.addObservation(kf, i, *point)) {
      active.eraseMapPoint(point->id());
      continue;
    }
    active.updateNormalAndDistances(*point);
    active.updateDescriptor(*point);
    frame.map_points[static_cast<std::size_t>(i)] = point->id();
    ++created;
  }
  return created;
}

void Tracker::extendMapAtPrediction(map::Frame& frame) {
  clearMatches(frame);
  last_frame_ = frame;
  // Every static keypoint with depth becomes a map point (close_depth_m does not apply here).
  const double saved_close = options_.close_depth_m;
  options_.close_depth_m = std::numeric_limits<double>::infinity();
  createKeyFrame();
  options_.close_depth_m = saved_close;
  frame.map_points = last_frame_->map_points;
  frame.outliers = last_frame_->outliers;
  frame.reference_keyframe = reference_kf_;
  last_tracked_t_s_ = frame.t_s();
  velocity_T_last_cur_.reset();
}

}  // namespace ltlo::tracking
