#include "ltlo/system/run_recorder.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_set>
#include <utility>

#include "ltlo/core/log.h"
#include "ltlo/core/undistorter.h"
#include "ltlo/loop/loop_closer.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/run_state_io.h"
#include "ltlo/system/carried_stretch.h"
#include "ltlo/tracking/tracker.h"

namespace ltlo::system {
namespace {

/// BGR of the raw image pixel nearest to each keypoint (ideal level-0 coordinates, taken back through
/// the lens when it distorts; clamped to the image).
std::vector<cv::Vec3b> sampleColours(const cv::Mat& color_bgr, const std::vector<features::Keypoint>& keypoints,
                                     const Undistorter& undistorter) {
  std::vector<cv::Vec3b> colours(keypoints.size(), cv::Vec3b(128, 128, 128));
  if (color_bgr.empty() || color_bgr.type() != CV_8UC3) return colours;
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    Vec2 u(keypoints[i].x_px, keypoints[i].y_px);
    if (undistorter.active()) u = undistorter.model().distortPixel(u);
    const int col = std::clamp(static_cast<int>(std::lround(u.x())), 0, color_bgr.cols - 1);
    const int row = std::clamp(static_cast<int>(std::lround(u.y())), 0, color_bgr.rows - 1);
    colours[i] = color_bgr.at<cv::Vec3b>(row, col);
  }
  return colours;
}

/// A frame record's IMU data for the inertial bridge (absent: a false flag).
void writeCarriedImu(const std::shared_ptr<const CarriedImu>& imu, map::ByteWriter& out) {
  out.boolean(imu != nullptr);
  if (!imu) return;
  out.boolean(imu->from_previous != nullptr);
  if (imu->from_previous) map::writePreintegration(*imu->from_previous, out);
  out.vec3(imu->v_w_b);
  out.vec3(imu->bias.b_g);
  out.vec3(imu->bias.b_a);
  out.vec3(imu->g_w);
  out.se3(imu->T_b_c);
}

std::shared_ptr<const CarriedImu> readCarriedImu(map::ByteReader& in) {
  if (!in.boolean("frame record IMU data")) return nullptr;
  auto imu = std::make_shared<CarriedImu>();
  if (in.boolean("frame record preintegration")) {
    imu->from_previous = std::make_shared<const imu::Preintegrated>(map::readPreintegration(in));
  }
  imu->v_w_b = in.vec3("frame record velocity");
  imu->bias.b_g = in.vec3("frame record gyro bias");
  imu->bias.b_a = in.vec3("frame record accelerometer bias");
  imu->g_w = in.vec3("frame record gravity");
  imu->T_b_c = in.se3("frame record T_b_c");
  return imu;
}

}  // namespace

RunRecorder::RunRecorder(map::Atlas& atlas, const TrackingOptions& tracking)
    : atlas_(atlas), tracking_(tracking), imu_retention_(tracking.carried_bridge_margin_s) {}

void RunRecorder::recordKeyFrameColours(const map::KeyFrame& kf, const cv::Mat& color_bgr,
                                        const Undistorter& undistorter) {
  std::vector<cv::Vec3b> colours = sampleColours(color_bgr, kf.keypoints(), undistorter);
  std::lock_guard<std::mutex> lock(mutex_);
  colours_[kf.id().value] = std::move(colours);
}

std::optional<RecordedFrame> RunRecorder::recordFrame(double t_s, const map::Frame& frame,
                                                      const tracking::Tracker& tracker) {
  ++frames_;
  if (!frame.hasPose()) return std::nullopt;
  FrameRecord record;
  record.t_s = t_s;
  record.tracked = tracker.frameTracked();
  const SE3 T_w_c = frame.T_w_c();
  record.T_w_c_online = T_w_c;
  if (std::shared_ptr<map::KeyFrame> reference = tracker.referenceKeyFramePtr()) {
    record.map_online = reference->mapId();
    record.T_refb_c = map::latestPose_T_w_b(*reference).inverse() * T_w_c;
    record.reference = std::move(reference);
  } else {
    record.T_w_c = T_w_c;
  }
  if (record.tracked) ++frames_tracked_;
  trackCarriedStretch(record, frame, tracker.imuPredicted_T_w_b());
  countLossPolicy(record, tracker);
  RecordedFrame recorded;
  recorded.tracked = record.tracked;
  recorded.carried = record.carried;
  recorded.map = record.map_online;
  std::shared_ptr<CarriedImu> imu;
  if (tracker.imuInitialised() && frame.imu_from_last_frame) {
    imu = std::make_shared<CarriedImu>();
    imu->from_previous = std::make_shared<const imu::Preintegrated>(*frame.imu_from_last_frame);
    imu->v_w_b = frame.v_w_b();
    imu->bias = frame.bias();
    imu->g_w = tracker.g_w();
    imu->T_b_c = frame.T_b_c();
  }
  const bool before_map = tracker.framePosedBeforeMap();
  if (before_map) ++frames_before_map_;
  const std::shared_ptr<const map::KeyFrame> reference = record.reference;
  const bool has_stretch_reference = record.stretch_reference != nullptr;
  std::vector<std::size_t> anchored;  // pre-map records given this frame's reference
  // The first map's first keyframe, at its creation pose in the dead reckoning's world (read before
  // mutex_, a leaf lock: the keyframe's pose has its own).
  std::optional<SE3> T_firstb_w;
  if (record.reference && !pre_map_records_.empty()) T_firstb_w = map::latestPose_T_w_b(*record.reference).inverse();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (T_firstb_w) {
      for (const std::size_t index : pre_map_records_) {
        FrameRecord& early = records_[index];
        early.reference = record.reference;
        early.T_refb_c = *T_firstb_w * early.T_w_c;
        early.map_online = record.map_online;
      }
      anchored.swap(pre_map_records_);
    }
    records_.push_back(std::move(record));
    if (before_map) pre_map_records_.push_back(records_.size() - 1);
    for (auto& [index, kept] :
         imu_retention_.add(records_.size() - 1, t_s, recorded.carried, recorded.map.value, std::move(imu))) {
      records_[index].imu = std::move(kept);
    }
  }
  // records_ grows on this thread only: its size and the records' keyframes are read without the lock.
  for (const std::size_t index : anchored) noteReference(reference, index);
  if (reference) noteReference(reference, records_.size() - 1);
  if (has_stretch_reference) whole_stretch_records_.push_back(records_.size() - 1);
  if (++frames_since_release_ >= kReleaseEveryFrames) {
    frames_since_release_ = 0;
    releaseCulledKeyFrames();
  }
  return recorded;
}

void RunRecorder::noteReference(const std::shared_ptr<const map::KeyFrame>& kf, std::size_t record) {
  if (!whole_references_.empty()) {
    ReferenceSpan& last = whole_references_.back();
    if (last.kf == kf && last.end == record) {
      last.end = record + 1;
      return;
    }
  }
  whole_references_.push_back({kf, record, record + 1});
}

std::shared_ptr<map::KeyFrame> RunRecorder::standInOf(const map::KeyFrame& kf) {
  const auto it = stand_ins_.find(kf.id());
  if (it != stand_ins_.end()) return it->second;
  std::shared_ptr<map::KeyFrame> stand_in = map::culledStandIn(kf);
  stand_ins_.emplace(kf.id(), stand_in);
  if (stand_in->culledParent()) stand_ins_with_whole_parent_.push_back(stand_in);
  return stand_in;
}

void RunRecorder::releaseCulledKeyFrames() {
  struct Swap {
    std::size_t first = 0;
    std::size_t end = 0;
    const map::KeyFrame* whole = nullptr;
    std::shared_ptr<map::KeyFrame> stand_in;
  };
  std::vector<Swap> swaps;
  std::size_t kept = 0;
  for (ReferenceSpan& span : whole_references_) {
    if (span.kf->isBad()) {
      swaps.push_back({span.first, span.end, span.kf.get(), standInOf(*span.kf)});
    } else {
      whole_references_[kept++] = std::move(span);
    }
  }
  whole_references_.resize(kept);
  std::vector<std::pair<std::size_t, std::shared_ptr<map::KeyFrame>>> stretch_swaps;
  kept = 0;
  for (const std::size_t index : whole_stretch_records_) {
    const std::shared_ptr<const map::KeyFrame>& kf = records_[index].stretch_reference;
    if (kf->isBad()) {
      stretch_swaps.emplace_back(index, standInOf(*kf));
    } else {
      whole_stretch_records_[kept++] = index;
    }
  }
  whole_stretch_records_.resize(kept);
  if (carried_reference_ && carried_reference_->isBad()) carried_reference_ = standInOf(*carried_reference_);
  // Stand-ins whose culled parent has been culled since: linked to the parent's stand-in (which may
  // join the list itself, so the chain is followed in this pass).
  for (std::size_t k = 0; k < stand_ins_with_whole_parent_.size();) {
    const std::shared_ptr<map::KeyFrame> stand_in = stand_ins_with_whole_parent_[k];
    const std::shared_ptr<map::KeyFrame> parent = stand_in->culledParent();
    const auto known = parent ? stand_ins_.find(parent->id()) : stand_ins_.end();
    const bool parent_is_stand_in = known != stand_ins_.end() && known->second == parent;
    if (parent && !parent_is_stand_in && !parent->isBad()) {
      ++k;
      continue;
    }
    if (parent && !parent_is_stand_in) stand_in->replaceCulledParent(standInOf(*parent));
    stand_ins_with_whole_parent_[k] = std::move(stand_ins_with_whole_parent_.back());
    stand_ins_with_whole_parent_.pop_back();
  }
  if (swaps.empty() && stretch_swaps.empty()) return;
  std::lock_guard<std::mutex> lock(mutex_);
  for (const Swap& swap : swaps) {
    for (std::size_t r = swap.first; r < swap.end; ++r) {
      if (records_[r].reference.get() == swap.whole) records_[r].reference = swap.stand_in;
    }
    colours_.erase(swap.stand_in->id().value);
  }
  for (auto& [index, stand_in] : stretch_swaps) records_[index].stretch_reference = std::move(stand_in);
}

void RunRecorder::trackCarriedStretch(FrameRecord& record, const map::Frame& frame,
                                      const std::optional<SE3>& predicted_T_w_b) {
  record.carried = !record.tracked && predicted_T_w_b && record.reference;
  if (record.tracked && carried_reference_ && predicted_T_w_b) {
    // The first frame anchored after an IMU-carried stretch: where the dead reckoning put it,
    // relative to the keyframe the stretch hung on (trajectory() spreads the difference).
    record.stretch_reference = carried_reference_;
    record.T_stretchrefb_c_predicted =
        map::latestPose_T_w_b(*carried_reference_).inverse() * (*predicted_T_w_b * frame.T_b_c());
  }
  if (record.tracked && carried_reference_ && !predicted_T_w_b) {
    log::debug("system: the frame at t = ", record.t_s, " s ends a carried stretch without an IMU prediction");
  }
  if (record.carried) {
    if (!carried_reference_) carried_reference_ = record.reference;
  } else {
    carried_reference_.reset();
  }
}

void RunRecorder::countLossPolicy(const FrameRecord& record, const tracking::Tracker& tracker) {
  const tracking::TrackingStats& stats = tracker.stats();
  if (record.tracked && stats.inertial_link != 0 && stats.inliers < tracking_.min_inliers) {
    ++frames_tracked_weak_imu_;
  }
  if (!record.tracked && stats.inertial_link != 0) ++frames_imu_predicted_;
  if (stats.relocalised) ++relocalisations_;
  if (stats.map_extended) ++maps_extended_;
  if (stats.reacquired) ++reacquisitions_;
}

double RunRecorder::firstPoseTime() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return records_.size() <= context_records_ ? std::numeric_limits<double>::quiet_NaN()
                                             : records_[context_records_].t_s;
}

SystemCounts RunRecorder::counts(const tracking::Tracker& tracker, const loop::LoopCloser& closer) const {
  SystemCounts counts;
  counts.frames = frames_;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    counts.frames_with_pose = static_cast<int>(records_.size() - context_records_);
  }
  counts.frames_tracked = frames_tracked_;
  const std::vector<map::MapId> map_ids = atlas_.mapIds();
  counts.maps = static_cast<int>(map_ids.size());
  counts.maps_created = tracker.numMapsCreated();
  counts.frames_tracked_weak_imu = frames_tracked_weak_imu_;
  counts.frames_imu_predicted = frames_imu_predicted_;
  counts.frames_before_map = frames_before_map_;
  counts.relocalisations = relocalisations_;
  counts.maps_extended = maps_extended_;
  counts.reacquisitions = reacquisitions_;
  counts.loops = closer.numLoops();
  counts.merges = closer.numMerges();
  for (const map::MapId map_id : map_ids) {
    if (const map::Map* map = atlas_.map(map_id)) {
      counts.keyframes += static_cast<int>(map->numKeyFrames());
      counts.map_points += static_cast<int>(map->numMapPoints());
    }
  }
  counts.imu_initialised = tracker.imuInitialised();
  counts.frames_localised_in_map = tracker.numFramesLocalisedInMap();
  counts.keyframes_released = static_cast<int>(stand_ins_.size());
  std::unordered_set<map::KeyFrameId> culled_held;
  for (const ReferenceSpan& span : whole_references_) {
    if (span.kf->isBad()) culled_held.insert(span.kf->id());
  }
  counts.keyframes_culled_held = static_cast<int>(culled_held.size());
  return counts;
}

std::unordered_map<map::MapId, map::MapId> RunRecorder::floatingMaps(const std::vector<FrameRecord>& records) const {
  std::unordered_map<map::MapId, MapFrameSpan> maps;
  for (const FrameRecord& record : records) {
    if (!record.reference) continue;
    const auto [it, inserted] = maps.try_emplace(record.reference->mapId());
    if (inserted) it->second.first_t_s = record.t_s;
    it->second.last_t_s = record.t_s;
  }
  for (auto& [id, span] : maps) {
    map::Map* map = atlas_.map(id);
    const std::optional<map::MapOrigin> origin = map != nullptr ? map->origin() : std::nullopt;
    if (origin) span.origin_parent = atlas_.resolve(origin->parent);
  }
  return floatingMapWorlds(maps, kFloatingMapMaxSpan_s, kFloatingMapMaxDepth);
}

std::vector<FramePose> RunRecorder::trajectory(CarriedCorrection correction) const {
  std::vector<FrameRecord> records;
  std::size_t context = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    records = records_;
    context = context_records_;
  }
  // Short maps started at the IMU's prediction and never merged: their coordinates are their
  // parent's world as the dead reckoning placed them, so their frames belong to the carried
  // stretch around them, and a frame anchored after it in that world ends it.
  const std::unordered_map<map::MapId, map::MapId> floating = floatingMaps(records);
  auto world_of = [&floating](map::MapId id) {
    const auto it = floating.find(id);
    return it == floating.end() ? id : it->second;
  };
  // Keyframe poses are read outside mutex_ (it is a leaf lock).
  std::vector<FramePose> poses;
  poses.reserve(records.size());
  std::vector<CarriedSample> samples;
  samples.reserve(records.size());
  for (const FrameRecord& record : records) {
    FramePose pose;
    pose.t_s = record.t_s;
    pose.tracked = record.tracked;
    CarriedSample sample;
    if (record.reference) {
      pose.T_w_c = map::latestPose_T_w_b(*record.reference) * record.T_refb_c;
      pose.map = record.reference->mapId();
      // Comparable only while the stretch's keyframe and this frame's lie in one world (one map
      // after merges, or a floating map of this frame's map).
      if (record.stretch_reference && floating.count(pose.map) == 0 &&
          world_of(record.stretch_reference->mapId()) == pose.map) {
        sample.T_w_c_dead_reckoned =
            map::latestPose_T_w_b(*record.stretch_reference) * record.T_stretchrefb_c_predicted;
      } else if (record.stretch_reference) {
        log::debug("trajectory: the frame at t = ", record.t_s, " s in ", pose.map, " (floating ",
                   floating.count(pose.map), ") ends a carried stretch hung on ", record.stretch_reference->id(),
                   " in ", record.stretch_reference->mapId(), ": not comparable");
      }
    } else {
      pose.T_w_c = record.T_w_c;
    }
    sample.t_s = pose.t_s;
    sample.T_w_c = pose.T_w_c;
    sample.carried = record.carried || (record.reference && floating.count(pose.map) > 0);
    sample.world = record.reference ? world_of(pose.map).value : map::MapId::kInvalid;
    if (record.imu && record.reference) {
      // Velocity and gravity turned with the reference keyframe since the frame was tracked.
      const Mat3 R_w_ref_then = (record.T_w_c_online * record.T_refb_c.inverse()).rotationMatrix();
      const Mat3 R_now_then = map::latestPose_T_w_b(*record.reference).rotationMatrix() * R_w_ref_then.transpose();
      auto imu = std::make_shared<CarriedImu>(*record.imu);
      imu->v_w_b = R_now_then * imu->v_w_b;
      imu->g_w = R_now_then * imu->g_w;
      sample.imu = std::move(imu);
    }
    poses.push_back(pose);
    samples.push_back(std::move(sample));
  }
  if (correction != CarriedCorrection::kNone) {
    CarriedCorrectionOptions options;
    options.bridge = correction == CarriedCorrection::kBridge;
    options.velocity_sigma_m_s = tracking_.carried_velocity_sigma_m_s;
    options.acc_bias_sigma_m_s2 = tracking_.acc_bias_sigma_m_s2;
    options.gyro_bias_sigma_rad_s = tracking_.carried_gyro_bias_sigma_rad_s;
    options.margin_s = tracking_.carried_bridge_margin_s;
    correctCarriedStretches(samples, options);
    for (std::size_t i = 0; i < poses.size(); ++i) poses[i].T_w_c = samples[i].T_w_c;
  }
  poses.erase(poses.begin(), poses.begin() + static_cast<std::ptrdiff_t>(context));  // a saved run's frames
  return poses;
}

std::vector<FramePose> RunRecorder::onlineTrajectory() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<FramePose> poses;
  poses.reserve(records_.size() - context_records_);
  for (std::size_t k = context_records_; k < records_.size(); ++k) {
    const FrameRecord& record = records_[k];
    FramePose pose;
    pose.t_s = record.t_s;
    pose.T_w_c = record.T_w_c_online;
    pose.tracked = record.tracked;
    pose.map = record.map_online;
    poses.push_back(pose);
  }
  return poses;
}

std::vector<Eigen::Vector3f> RunRecorder::framePositionsInMap(map::MapId map_id) const {
  // The frames so far, from their reference keyframes' latest poses (loop corrections move them);
  // the records are copied under their leaf lock, the keyframes read after it.
  std::vector<std::pair<std::shared_ptr<const map::KeyFrame>, SE3>> references;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    references.reserve(records_.size());
    for (const FrameRecord& record : records_) {
      if (record.reference) references.emplace_back(record.reference, record.T_refb_c);
    }
  }
  std::vector<Eigen::Vector3f> positions_w;
  positions_w.reserve(references.size());
  for (const auto& [reference, T_refb_c] : references) {
    if (reference->mapId() != map_id) continue;
    positions_w.push_back((map::latestPose_T_w_b(*reference) * T_refb_c).translation().cast<float>());
  }
  return positions_w;
}

std::vector<KeyFrameRecord> RunRecorder::keyFrames() const {
  std::vector<KeyFrameRecord> keyframes;
  for (const map::MapId map_id : atlas_.mapIds()) {
    const map::Map* map = atlas_.map(map_id);
    if (map == nullptr) continue;
    for (const std::shared_ptr<map::KeyFrame>& kf : map->keyFrames()) {
      if (kf->isBad()) continue;
      KeyFrameRecord record;
      record.t_s = kf->t_s();
      record.T_w_c = kf->T_w_c();
      record.id = kf->id().value;
      record.map = kf->mapId().value;
      record.static_area_ratio = kf->staticAreaRatio();
      keyframes.push_back(record);
    }
  }
  std::sort(keyframes.begin(), keyframes.end(),
            [](const KeyFrameRecord& a, const KeyFrameRecord& b) { return a.t_s < b.t_s; });
  return keyframes;
}

std::vector<MapPointRecord> RunRecorder::mapPoints() const {
  struct PointSource {
    MapPointRecord record;
    std::vector<std::pair<std::uint64_t, int>> observations;  // reference keyframe first
  };
  std::vector<PointSource> sources;
  for (const std::shared_ptr<map::MapPoint>& point : atlas_.activeMap().mapPoints()) {
    if (point->isBad()) continue;
    PointSource source;
    source.record.p_w = point->p_w();
    source.record.beta = point->beta();
    for (const auto& [kf_id, index] : point->observations()) {
      if (const std::shared_ptr<map::KeyFrame> kf = atlas_.activeMap().keyFrame(kf_id)) {
        source.record.observer_centres_w.push_back(kf->cameraCentre_w());
      }
    }
    const map::KeyFrameId reference = point->referenceKeyFrame();
    if (const std::optional<int> index = point->indexIn(reference)) {
      source.observations.emplace_back(reference.value, *index);
    }
    for (const auto& [kf, index] : point->observations()) source.observations.emplace_back(kf.value, index);
    sources.push_back(std::move(source));
  }
  std::vector<MapPointRecord> points;
  points.reserve(sources.size());
  std::lock_guard<std::mutex> lock(mutex_);
  for (PointSource& source : sources) {
    for (const auto& [kf, index] : source.observations) {
      const auto found = colours_.find(kf);
      if (found == colours_.end() || index < 0 || index >= static_cast<int>(found->second.size())) continue;
      const cv::Vec3b bgr = found->second[static_cast<std::size_t>(index)];
      source.record.blue = bgr[0];
      source.record.green = bgr[1];
      source.record.red = bgr[2];
      break;
    }
    points.push_back(source.record);
  }
  return points;
}

void RunRecorder::writeState(map::ByteWriter& out, map::KeyFrameRefs& refs) const {
  std::vector<FrameRecord> records;
  std::unordered_map<std::uint64_t, std::vector<cv::Vec3b>> colours;
  CarriedImuRetention::State retention;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    records = records_;
    colours = colours_;
    retention = imu_retention_.state();
  }
  out.u64(records.size());
  for (const FrameRecord& record : records) {
    out.f64(record.t_s);
    refs.write(record.reference, out);
    out.se3(record.T_refb_c);
    out.se3(record.T_w_c);
    out.boolean(record.tracked);
    out.boolean(record.carried);
    refs.write(record.stretch_reference, out);
    out.se3(record.T_stretchrefb_c_predicted);
    out.se3(record.T_w_c_online);
    out.u64(record.map_online.value);
    writeCarriedImu(record.imu, out);
  }
  refs.write(carried_reference_, out);
  // The frames held back in case a carried stretch follows, and where the last stretch stands.
  out.u64(retention.recent.size());
  for (const CarriedImuRetention::Pending& pending : retention.recent) {
    out.u64(pending.index);
    out.f64(pending.t_s);
    out.u64(pending.map);
    writeCarriedImu(pending.imu, out);
  }
  out.boolean(retention.stretch_open);
  out.u64(retention.stretch_map);
  out.f64(retention.last_carried_t_s);
  out.f64(retention.keep_until_s);
  // The colours of the keyframes that can still give a point its colour (those in the maps), by id.
  std::vector<std::uint64_t> ids;
  for (const map::MapId map_id : atlas_.mapIds()) {
    for (const std::shared_ptr<map::KeyFrame>& kf : atlas_.map(map_id)->keyFrames()) {
      if (!kf->isBad() && colours.count(kf->id().value) > 0) ids.push_back(kf->id().value);
    }
  }
  std::sort(ids.begin(), ids.end());
  out.u64(ids.size());
  for (const std::uint64_t id : ids) {
    const std::vector<cv::Vec3b>& keypoints = colours.at(id);
    out.u64(id);
    out.u64(keypoints.size());
    for (const cv::Vec3b& bgr : keypoints) out.raw(&bgr[0], 3);
  }
}

void RunRecorder::readState(map::ByteReader& in, const map::RunKeyFrames& keyframes) {
  constexpr std::size_t kRecordBytes = 8 + 8 + 56 + 56 + 1 + 1 + 8 + 56 + 56 + 8 + 1;
  const std::size_t n = in.count("frame records", kRecordBytes);
  std::vector<FrameRecord> records(n);
  for (FrameRecord& record : records) {
    record.t_s = in.finiteF64("frame record time");
    record.reference = keyframes.read(in, "frame record reference");
    record.T_refb_c = in.se3("frame record T_refb_c");
    record.T_w_c = in.se3("frame record T_w_c");
    record.tracked = in.boolean("frame record tracked");
    record.carried = in.boolean("frame record carried");
    record.stretch_reference = keyframes.read(in, "frame record stretch reference");
    record.T_stretchrefb_c_predicted = in.se3("frame record stretch prediction");
    record.T_w_c_online = in.se3("frame record online pose");
    record.map_online = map::MapId(in.u64("frame record map"));
    record.imu = readCarriedImu(in);
  }
  carried_reference_ = keyframes.read(in, "carried stretch reference");
  CarriedImuRetention::State retention;
  const std::size_t num_pending = in.count("frames held for a carried stretch", 8 + 8 + 8 + 1);
  for (std::size_t k = 0; k < num_pending; ++k) {
    const std::uint64_t offset = in.fileOffset();
    CarriedImuRetention::Pending pending;
    pending.index = in.u64("held frame record");
    if (pending.index >= records.size()) {
      in.failAt(offset, "a held frame beyond the " + std::to_string(records.size()) + " frame records",
                std::to_string(pending.index));
    }
    pending.t_s = in.finiteF64("held frame time");
    pending.map = in.u64("held frame map");
    pending.imu = readCarriedImu(in);
    retention.recent.push_back(std::move(pending));
  }
  retention.stretch_open = in.boolean("carried stretch open");
  retention.stretch_map = in.u64("carried stretch map");
  retention.last_carried_t_s = in.finiteF64("last carried frame time");
  retention.keep_until_s = in.finiteF64("carried data kept until");
  const std::size_t num_colours = in.count("keyframe colours", 16);
  std::unordered_map<std::uint64_t, std::vector<cv::Vec3b>> colours;
  for (std::size_t k = 0; k < num_colours; ++k) {
    const std::uint64_t offset = in.fileOffset();
    const std::uint64_t id = in.u64("coloured keyframe");
    std::vector<cv::Vec3b>& keypoints = colours[id];
    if (!keypoints.empty()) in.failAt(offset, "keyframe colours given twice", std::to_string(id));
    keypoints.resize(in.count("keypoint colours", 3));
    for (cv::Vec3b& bgr : keypoints) in.raw(&bgr[0], 3, "keypoint colour");
  }
  // The restored records' live keyframes are swapped for stand-ins once culled, as this run's.
  whole_references_.clear();
  whole_stretch_records_.clear();
  for (std::size_t r = 0; r < records.size(); ++r) {
    if (records[r].reference && !records[r].reference->isBad()) noteReference(records[r].reference, r);
    if (records[r].stretch_reference && !records[r].stretch_reference->isBad()) whole_stretch_records_.push_back(r);
  }
  std::lock_guard<std::mutex> lock(mutex_);
  records_ = std::move(records);
  context_records_ = records_.size();
  // A run saved before its first map: the restored records keep their dead-reckoned poses as they
  // are (the resumed tracker starts its own dead reckoning).
  pre_map_records_.clear();
  colours_ = std::move(colours);
  imu_retention_.restore(std::move(retention));
}

}  // namespace ltlo::system
