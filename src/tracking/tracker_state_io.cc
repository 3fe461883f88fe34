// Tracker, part 8: the tracker's state between two frames in the atlas file's run state
// (ltlo/map/run_state_io.h, system/run_state.h), so a run resumed from the file tracks its next
// frame exactly as the saved run would have. Written: every member a later frame reads (the last
// frame whole, the motion models, the inertial link's state and marginal, the keyframe references,
// the loss policy, the loaded-atlas start, localisation only's odometry and IMU window, the
// standstill test, the occluded start's provisional points). Not written: what each frame sets
// afresh before reading it (stats_, frame_information_, imu_prediction_, segmentation_outcome_, the
// odometry's per-frame buffers), pure statistics (num_keyframes_, frames_localised_in_map_) and the
// initialisation's wait (logging only).
#include <cmath>
#include <limits>
#include <string>

#include "ltlo/map/run_state_io.h"
#include "ltlo/tracking/tracker.h"

namespace ltlo::tracking {

namespace {

constexpr std::size_t kIdBytes = 8;

void writeInformation(bool valid, const Mat15& information, map::ByteWriter& out) {
  out.boolean(valid);
  if (valid) map::writeMatrix(information, out);
}

template <typename Id>
void writeIds(const std::vector<Id>& ids, map::ByteWriter& out) {
  out.u64(ids.size());
  for (const Id id : ids) out.u64(id.value);
}

template <typename Id>
std::vector<Id> readIds(map::ByteReader& in, const char* what) {
  const std::size_t n = in.count(what, kIdBytes);
  std::vector<Id> ids(n);
  for (Id& id : ids) id = Id(in.u64(what));
  return ids;
}

std::optional<double> readOptionalTime(map::ByteReader& in, const char* what) {
  if (!in.boolean(what)) return std::nullopt;
  return in.finiteF64(what);
}

}  // namespace

void Tracker::writeState(map::ByteWriter& out, map::KeyFrameRefs& refs) const {
  out.u8(static_cast<std::uint8_t>(state_));
  out.boolean(frame_tracked_);
  out.boolean(last_frame_.has_value());
  if (last_frame_) map::writeFrame(*last_frame_, out);
  out.se3(last_T_w_c_);
  map::writeOptionalSe3(velocity_T_last_cur_, out);
  out.f64(velocity_dt_s_);
  out.i32(frames_since_keyframe_);
  out.boolean(resumed_without_keyframe_);
  out.f64(last_keyframe_t_s_);
  out.u64(reference_kf_.value);
  refs.write(reference_kf_ptr_, out);
  out.u64(last_kf_.value);
  refs.write(last_kf_ptr_, out);
  out.se3(last_kf_T_w_b_seen_);
  out.vec3(last_kf_v_w_b_seen_);
  map::writeBias(last_kf_bias_seen_, out);
  out.u64(map_id_.value);
  out.u64(map_version_);
  out.se3(T_refb_c_last_);
  out.se3(prev_T_w_b_);
  out.vec3(prev_v_w_b_);
  out.f64(prev_t_s_);
  out.f64(last_tracked_t_s_);
  loss_.writeState(out);
  writeIds(local_keyframes_, out);
  writeIds(local_points_, out);

  // A run in a loaded atlas.
  out.boolean(loaded_start_pending_);
  out.boolean(loaded_start_t_s_.has_value());
  if (loaded_start_t_s_) out.f64(*loaded_start_t_s_);
  out.boolean(loaded_start_new_map_);
  out.boolean(velocity_unknown_);
  out.boolean(deferred_imu_.has_value());
  if (deferred_imu_) {
    map::writeBias(deferred_imu_->bias, out);
    out.vec3(deferred_imu_->g_w);
    out.f64(deferred_imu_->acceleration_sigma_m_s2);
  }
  out.boolean(start_velocity_.has_value());
  if (start_velocity_) {
    out.se3(start_velocity_->T_w_b0);
    out.f64(start_velocity_->t0_s);
    map::writeOptionalPreintegration(start_velocity_->imu_since_anchor, out);
    out.vec3(start_velocity_->weighted_v0);
    out.f64(start_velocity_->weight);
  }

  // Localisation only.
  out.u64(odometry_points_.size());
  for (const OdometryPoint& point : odometry_points_) {
    out.vec3(point.p_w);
    for (const std::uint64_t word : point.descriptor) out.u64(word);
    out.i32(point.octave);
  }
  out.f64(last_map_localised_t_s_);
  const LocalisationImuWindow& window = localisation_imu_;
  out.u64(window.T_w_b.size());
  for (std::size_t k = 0; k < window.T_w_b.size(); ++k) {
    out.se3(window.T_w_b[k]);
    out.f64(window.t_s[k]);
  }
  out.u64(window.pims.size());
  for (const std::shared_ptr<const imu::Preintegrated>& pim : window.pims) map::writePreintegration(*pim, out);
  map::writeOptionalPreintegration(window.since_newest, out);
  out.f64(window.last_estimate_t_s);

  // The IMU.
  out.boolean(imu_initialised_);
  out.boolean(early_keyframes_after_init_);
  out.f64(init_acceleration_sigma_m_s2_);
  map::writeBias(bias_, out);
  out.vec3(g_w_);
  out.boolean(imu_since_keyframe_ != nullptr);
  if (imu_since_keyframe_) map::writePreintegration(*imu_since_keyframe_, out);
  out.boolean(imu_chain_broken_);
  out.boolean(link_to_keyframe_);
  out.boolean(last_kf_inertial_);
  writeInformation(prev_information_.valid, prev_information_.information, out);
  map::writeBias(prev_bias_, out);

  // Standstill.
  out.boolean(zero_velocity_.has_value());
  if (zero_velocity_) {
    const imu::ZeroVelocityDetector::State detector = zero_velocity_->state();
    map::writeImuSamples(ImuSamples(detector.window.begin(), detector.window.end()), out);
    out.boolean(detector.tested);
    const imu::ZeroVelocityStatistics& statistics = detector.statistics;
    out.f64(statistics.gyro_ratio);
    out.f64(statistics.acc_ratio);
    out.f64(statistics.newest_gyro_ratio);
    out.f64(statistics.newest_acc_ratio);
    out.i32(statistics.samples);
    out.boolean(statistics.still);
  }
  out.boolean(still_);
  out.f64(still_from_t_s_);
  map::writeBias(still_bias_, out);
  out.boolean(rest_keyframe_made_);
  out.boolean(link_last_frame_after_rest_);

  // Occluded start (tracker_start.cc).
  out.u64(provisional_points_.size());
  for (const ProvisionalPoint& point : provisional_points_) {
    out.u64(point.id.value);
    out.i32(point.dynamic_votes);
    out.i32(point.static_votes);
  }
  out.f64(provisional_from_t_s_);
  out.f64(start_window_end_t_s_);
  out.i32(provisional_erased_);

  // Tracking.StartMotionCheck (tracker_start.cc).
  const imu::PoseGravityCheck::State& motion = start_motion_.state();
  out.u64(motion.nodes.size());
  for (const imu::PoseGravityCheck::Node& node : motion.nodes) {
    out.f64(node.t_s);
    out.mat3(node.R_w_b);
    out.vec3(node.p_w_b);
    out.f64(node.sigma_m);
  }
  const auto writeInterval = [&out](const imu::PoseGravityCheck::Interval& interval) {
    out.mat3(interval.dR);
    out.vec3(interval.dV);
    out.vec3(interval.dP);
    out.f64(interval.dt_s);
  };
  out.u64(motion.intervals.size());
  for (const imu::PoseGravityCheck::Interval& interval : motion.intervals) writeInterval(interval);
  writeInterval(motion.open);
  out.vec3(motion.g_sum);
  out.i32(motion.windows);
  out.f64(motion.max_error_m_s2);
  out.i32(start_motion_recoveries_);
}

void Tracker::readState(map::ByteReader& in, const map::RunKeyFrames& keyframes) {
  const std::uint64_t state_offset = in.fileOffset();
  const std::uint8_t state = in.u8("tracking state");
  if (state > static_cast<std::uint8_t>(TrackingState::kLost)) {
    in.failAt(state_offset, "tracking state out of [0, 2]", std::to_string(state));
  }
  state_ = static_cast<TrackingState>(state);
  frame_tracked_ = in.boolean("frame tracked");
  last_frame_.reset();
  if (in.boolean("has a last frame")) last_frame_ = map::readFrame(in, vocabulary_);
  if (state_ != TrackingState::kNotInitialised && !last_frame_) {
    in.failAt(state_offset, "tracking initialised without a last frame", std::to_string(state));
  }
  last_T_w_c_ = in.se3("last T_w_c");
  velocity_T_last_cur_ = map::readOptionalSe3(in, "constant-velocity motion");
  velocity_dt_s_ = in.finiteF64("constant-velocity interval");
  frames_since_keyframe_ = in.i32InRange("frames since the keyframe", 0, std::numeric_limits<std::int32_t>::max());
  resumed_without_keyframe_ = in.boolean("resumed without a keyframe");
  last_keyframe_t_s_ = in.finiteF64("last keyframe time");
  reference_kf_ = map::KeyFrameId(in.u64("reference keyframe id"));
  reference_kf_ptr_ = keyframes.read(in, "reference keyframe");
  last_kf_ = map::KeyFrameId(in.u64("last keyframe id"));
  last_kf_ptr_ = keyframes.read(in, "last keyframe");
  last_kf_T_w_b_seen_ = in.se3("last keyframe pose seen");
  last_kf_v_w_b_seen_ = in.vec3("last keyframe velocity seen");
  last_kf_bias_seen_ = map::readBias(in, "last keyframe bias seen");
  map_id_ = map::MapId(in.u64("tracked map"));
  map_version_ = in.u64("tracked map version");
  T_refb_c_last_ = in.se3("T_refb_c of the last frame");
  prev_T_w_b_ = in.se3("previous T_w_b");
  prev_v_w_b_ = in.vec3("previous velocity");
  prev_t_s_ = in.finiteF64("previous frame time");
  last_tracked_t_s_ = in.finiteF64("last tracked time");
  loss_.readState(in);
  local_keyframes_ = readIds<map::KeyFrameId>(in, "local keyframes");
  local_points_ = readIds<map::MapPointId>(in, "local map points");

  loaded_start_pending_ = in.boolean("loaded start pending");
  loaded_start_t_s_ = readOptionalTime(in, "loaded start time");
  loaded_start_new_map_ = in.boolean("loaded start made a new map");
  velocity_unknown_ = in.boolean("velocity unknown");
  deferred_imu_.reset();
  if (in.boolean("has a deferred IMU state")) {
    DeferredImu deferred;
    deferred.bias = map::readBias(in, "deferred bias");
    deferred.g_w = in.vec3("deferred gravity");
    deferred.acceleration_sigma_m_s2 = in.finiteF64("deferred acceleration sigma");
    deferred_imu_ = deferred;
  }
  start_velocity_.reset();
  if (in.boolean("has a start velocity fit")) {
    StartVelocityFit fit;
    fit.T_w_b0 = in.se3("start velocity anchor pose");
    fit.t0_s = in.finiteF64("start velocity anchor time");
    fit.imu_since_anchor = map::readOptionalPreintegration(in);
    fit.weighted_v0 = in.vec3("start velocity sum");
    fit.weight = in.finiteF64("start velocity weight");
    start_velocity_ = std::move(fit);
  }

  const std::size_t num_points = in.count("odometry points", 24 + 32 + 4);
  odometry_points_.assign(num_points, OdometryPoint());
  for (OdometryPoint& point : odometry_points_) {
    point.p_w = in.vec3("odometry point");
    for (std::uint64_t& word : point.descriptor) word = in.u64("odometry point descriptor");
    point.octave = in.i32InRange("odometry point octave", 0, static_cast<std::int32_t>(level_sigma2_.size()) - 1);
  }
  last_map_localised_t_s_ = in.finiteF64("last map-localised time");
  LocalisationImuWindow window;
  const std::size_t num_nodes = in.count("localisation IMU nodes", 56 + 8);
  for (std::size_t k = 0; k < num_nodes; ++k) {
    window.T_w_b.push_back(in.se3("localisation IMU node pose"));
    window.t_s.push_back(in.finiteF64("localisation IMU node time"));
  }
  const std::uint64_t pims_offset = in.fileOffset();
  const std::size_t num_pims = in.count("localisation IMU links", 8);
  if (num_pims + 1 != num_nodes && !(num_pims == 0 && num_nodes == 0)) {
    in.failAt(pims_offset, "localisation IMU links for " + std::to_string(num_nodes) + " nodes",
              std::to_string(num_pims));
  }
  for (std::size_t k = 0; k < num_pims; ++k) {
    window.pims.push_back(std::make_shared<const imu::Preintegrated>(map::readPreintegration(in)));
  }
  window.since_newest = map::readOptionalPreintegration(in);
  window.last_estimate_t_s = in.finiteF64("localisation IMU estimate time");
  localisation_imu_ = std::move(window);

  imu_initialised_ = in.boolean("IMU initialised");
  early_keyframes_after_init_ = in.boolean("early keyframes after the IMU initialisation");
  init_acceleration_sigma_m_s2_ = in.finiteF64("IMU acceleration sigma");
  bias_ = map::readBias(in, "tracking bias");
  g_w_ = in.vec3("tracking gravity");
  imu_since_keyframe_.reset();
  if (in.boolean("has IMU since the keyframe")) {
    imu_since_keyframe_ = std::make_shared<imu::Preintegrated>(map::readPreintegration(in));
  }
  imu_chain_broken_ = in.boolean("IMU chain broken");
  link_to_keyframe_ = in.boolean("link to the keyframe");
  last_kf_inertial_ = in.boolean("last keyframe inertial");
  prev_information_ = StateInformation();
  if (in.boolean("previous state has information")) {
    prev_information_.valid = true;
    prev_information_.information = map::readMatrix<15, 15>(in, "previous state information");
  }
  prev_bias_ = map::readBias(in, "previous bias");

  zero_velocity_.reset();
  if (in.boolean("has a zero-velocity test")) {
    imu::ZeroVelocityDetector::State detector;
    const ImuSamples window_samples = map::readImuSamples(in, "zero-velocity window");
    detector.window.assign(window_samples.begin(), window_samples.end());
    detector.tested = in.boolean("zero-velocity window tested");
    detector.statistics.gyro_ratio = in.finiteF64("zero-velocity statistics");
    detector.statistics.acc_ratio = in.finiteF64("zero-velocity statistics");
    detector.statistics.newest_gyro_ratio = in.finiteF64("zero-velocity statistics");
    detector.statistics.newest_acc_ratio = in.finiteF64("zero-velocity statistics");
    detector.statistics.samples = in.i32InRange("zero-velocity samples", 0, std::numeric_limits<std::int32_t>::max());
    detector.statistics.still = in.boolean("zero-velocity still");
    zero_velocity_.emplace(options_.zero_velocity);
    zero_velocity_->restore(std::move(detector));
  }
  still_ = in.boolean("still");
  still_from_t_s_ = in.finiteF64("still from");
  still_bias_ = map::readBias(in, "still bias");
  rest_keyframe_made_ = in.boolean("rest keyframe made");
  link_last_frame_after_rest_ = in.boolean("link to the last frame after rest");

  constexpr std::int32_t kMaxCount = std::numeric_limits<std::int32_t>::max();
  provisional_points_.resize(in.count("provisional points", kIdBytes + 8));
  for (ProvisionalPoint& point : provisional_points_) {
    point.id = map::MapPointId(in.u64("provisional point"));
    point.dynamic_votes = in.i32InRange("provisional point's dynamic votes", 0, kMaxCount);
    point.static_votes = in.i32InRange("provisional point's static votes", 0, kMaxCount);
  }
  provisional_from_t_s_ = in.finiteF64("provisional from");
  // -infinity without a start window, like the live value.
  const std::uint64_t window_offset = in.fileOffset();
  start_window_end_t_s_ = in.f64("start window end");
  if (std::isnan(start_window_end_t_s_) || start_window_end_t_s_ == std::numeric_limits<double>::infinity()) {
    in.failAt(window_offset, "start window end is not a time", map::exactNumberText(start_window_end_t_s_));
  }
  provisional_erased_ = in.i32InRange("provisional points erased", 0, kMaxCount);

  imu::PoseGravityCheck::State motion;
  const std::uint64_t nodes_offset = in.fileOffset();
  motion.nodes.resize(in.count("start motion check nodes", 8 + 9 * 8 + 3 * 8 + 8));
  if (motion.nodes.size() > 3) in.failAt(nodes_offset, "more than 3 start motion check nodes", std::to_string(motion.nodes.size()));
  for (imu::PoseGravityCheck::Node& node : motion.nodes) {
    node.t_s = in.finiteF64("start motion check node time");
    node.R_w_b = in.mat3("start motion check node rotation");
    node.p_w_b = in.vec3("start motion check node position");
    node.sigma_m = in.finiteF64("start motion check node sigma");
  }
  const auto readInterval = [&in]() {
    imu::PoseGravityCheck::Interval interval;
    interval.dR = in.mat3("start motion check interval");
    interval.dV = in.vec3("start motion check interval");
    interval.dP = in.vec3("start motion check interval");
    interval.dt_s = in.finiteF64("start motion check interval");
    return interval;
  };
  const std::uint64_t intervals_offset = in.fileOffset();
  motion.intervals.resize(in.count("start motion check intervals", 9 * 8 + 6 * 8 + 8));
  if (motion.intervals.size() + 1 != std::max<std::size_t>(motion.nodes.size(), 1)) {
    in.failAt(intervals_offset, "start motion check intervals do not join its " + std::to_string(motion.nodes.size()) + " nodes",
              std::to_string(motion.intervals.size()));
  }
  for (imu::PoseGravityCheck::Interval& interval : motion.intervals) interval = readInterval();
  motion.open = readInterval();
  motion.g_sum = in.vec3("start motion check gravity sum");
  motion.windows = in.i32InRange("start motion check windows", 0, kMaxCount);
  motion.max_error_m_s2 = in.finiteF64("start motion check largest difference");
  start_motion_.restore(std::move(motion));
  start_motion_recoveries_ = in.i32InRange("start motion check recoveries", 0, kMaxCount);
}

}  // namespace ltlo::tracking
