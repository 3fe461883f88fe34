// Tracker, part 5: the start of a run in a loaded atlas (System's --load-atlas). The atlas holds
// the maps of an earlier run in the same place; instead of starting a new world at its first frame,
// the run starts lost in them: each frame is relocalised (BoW candidates, RANSAC, the local-map
// search, relocaliser.h) in the loaded maps until one is, and from then on is tracked in that map's
// world frame, so its trajectory needs no alignment to the earlier run's. What the segmentation
// labels dynamic (a box parked where the map saw a wall) takes no part in the relocalisation.
// Not relocalised within Tracking.LoadedAtlasNewMapAfter of the first frame (a view the earlier run
// never saw, or an occluder filling it), the run starts a new map as a run without an atlas would;
// the loop closer merges it into the loaded map once it recognises a place there (map_merger.h).
// With Tracking.LocalisationOnly no map is ever started: frames stay without a pose until one is
// relocalised.
#include "ltlo/core/log.h"
#include "ltlo/tracking/tracker.h"
#include "tracker_util.h"

namespace ltlo::tracking {

using detail::clearMatches;

namespace {
/// Tracked time after the anchor frame over which the start velocity is fitted (s): at 1-2 mm of
/// pose noise the fit's velocity is within about 1 cm/s.
constexpr double kStartVelocityBaselineS = 0.3;
}  // namespace

TrackingState Tracker::startInLoadedAtlas(map::Frame& frame) {
  if (!loaded_start_t_s_) {
    loaded_start_t_s_ = frame.t_s();
    log::info("loaded atlas: ", atlas_.numMaps(), " map(s); relocalising from t = ", frame.t_s(), " s");
  }
  clearMatches(frame);
  const double waited_s = frame.t_s() - *loaded_start_t_s_;
  const double new_map_after_s = options_.tracking.loaded_atlas_new_map_after_s;
  const bool may_start_map = !options_.tracking.localisation_only && new_map_after_s >= 0.0;
  if (!may_start_map || waited_s < new_map_after_s) {
    const int inliers = relocaliseInAnyMap(frame);
    if (inliers > 0) {
      startAtRelocalisedFrame(frame, inliers);
      return TrackingState::kOk;
    }
    clearMatches(frame);
    if (!may_start_map || waited_s < new_map_after_s) return TrackingState::kNotInitialised;
  }
  // The new map's world is unrelated to the loaded ones' until a merge places it.
  map::Map& created = atlas_.createNewMap();
  const TrackingState state = initialise(frame);
  if (state == TrackingState::kOk) {
    loaded_start_pending_ = false;
    loaded_start_new_map_ = true;
    log::warn("loaded atlas: not relocalised in ", waited_s, " s (Tracking.LoadedAtlasNewMapAfter = ",
              new_map_after_s, " s): new map ", created.id(), " at t = ", frame.t_s(),
              " s, merged with a loaded map when the loop closer recognises one");
  }
  return state;
}

int Tracker::relocaliseInAnyMap(map::Frame& frame) {
  std::vector<map::MapId> order{atlas_.activeMapId()};
  for (const map::MapId id : atlas_.mapIds()) {
    if (id != order.front()) order.push_back(id);
  }
  const map::MapId active_before = order.front();
  for (const map::MapId id : order) {
    const map::Map* candidate = atlas_.map(id);
    if (candidate == nullptr || candidate->numKeyFrames() == 0) continue;
    // Nothing but tracking uses the atlas before the run's first pose: switching is safe.
    if (id != atlas_.activeMapId()) atlas_.setActiveMap(id);
    const int inliers = relocalise(frame);
    if (inliers > 0) return inliers;
  }
  if (atlas_.activeMapId() != active_before) atlas_.setActiveMap(active_before);
  return 0;
}

void Tracker::startAtRelocalisedFrame(map::Frame& frame, int inliers) {
  map::Map& active = activeMap();
  map_id_ = active.id();
  map_version_ = active.version();
  // No motion is known yet: the constant-velocity model and the IMU start from this frame.
  velocity_T_last_cur_.reset();
  if (!imu_initialised_) frame.setVelocity(Vec3::Zero());
  imu_since_keyframe_.reset();
  imu_chain_broken_ = false;
  frame_information_ = StateInformation();
  link_to_keyframe_ = true;
  last_kf_ = map::KeyFrameId();
  last_kf_ptr_.reset();
  last_keyframe_t_s_ = frame.t_s();
  frames_since_keyframe_ = 0;
  stats_.relocalised = true;
  stats_.inliers = inliers;
  frame.reference_keyframe = reference_kf_;  // the local map's (updateLocalMap)
  last_frame_ = frame;
  last_T_w_c_ = frame.T_w_c();
  last_tracked_t_s_ = frame.t_s();
  last_map_localised_t_s_ = frame.t_s();
  frame_map_localised_ = true;
  if (options_.tracking.localisation_only) ++frames_localised_in_map_;
  recordFramePose(frame);
  if (options_.tracking.localisation_only) keepOdometryPoints(frame);
  loaded_start_pending_ = false;
  start_velocity_.reset();
  estimateStartVelocity(frame, true);
  log::info("loaded atlas: relocalised in map ", active.id(), " at t = ", frame.t_s(), " s, ",
            frame.t_s() - *loaded_start_t_s_, " s after the first frame, ", inliers, " inliers, p = ",
            frame.T_w_c().translation().transpose());
}

void Tracker::estimateStartVelocity(map::Frame& frame, bool re_anchor) {
  if (re_anchor || !start_velocity_) {
    start_velocity_ = StartVelocityFit{frame.T_w_b(), frame.t_s(), std::nullopt, Vec3::Zero(), 0.0};
    return;
  }
  StartVelocityFit& fit = *start_velocity_;
  if (!frame.imu_from_last_frame) {
    start_velocity_.reset();  // no IMU across this interval: the fit starts again at the next frame
    return;
  }
  if (!fit.imu_since_anchor) {
    fit.imu_since_anchor = *frame.imu_from_last_frame;
  } else {
    fit.imu_since_anchor->append(*frame.imu_from_last_frame);
  }
  const double dt = frame.t_s() - fit.t0_s;
  if (dt <= 0.0) return;
  const imu::ImuBias bias = deferred_imu_ ? deferred_imu_->bias : bias_;
  const Vec3 g_w = deferred_imu_ ? deferred_imu_->g_w : g_w_;
  const Mat3 R_w_b0 = fit.T_w_b0.rotationMatrix();
  const Vec3 dp = fit.imu_since_anchor->correctedDeltaP(bias);
  const Vec3 v0 = (frame.T_w_b().translation() - fit.T_w_b0.translation() - 0.5 * g_w * dt * dt - R_w_b0 * dp) / dt;
  fit.weighted_v0 += dt * dt * v0;
  fit.weight += dt * dt;
  if (dt < kStartVelocityBaselineS) return;
  const Vec3 v_w_b = fit.weighted_v0 / fit.weight + g_w * dt + R_w_b0 * fit.imu_since_anchor->correctedDeltaV(bias);
  velocity_unknown_ = false;
  start_velocity_.reset();
  frame.setVelocity(v_w_b);
  if (last_frame_) last_frame_->setVelocity(v_w_b);
  prev_v_w_b_ = v_w_b;
  log::info("loaded atlas: velocity ", v_w_b.transpose(), " m/s at t = ", frame.t_s(), " s (fitted over ", dt,
            " s of tracked frames)", deferred_imu_ ? "; the loaded IMU state applies from here" : "");
  if (deferred_imu_) {
    const DeferredImu imu = *deferred_imu_;
    deferred_imu_.reset();
    setImuInitialised(imu.bias, imu.g_w, imu.acceleration_sigma_m_s2);
  }
}

}  // namespace ltlo::tracking
