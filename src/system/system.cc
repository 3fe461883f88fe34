#include "ltlo/system/system.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "bow/vocabulary.h"
#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/core/undistorter.h"
#include "ltlo/loop/loop_closer.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/mapping/local_mapper.h"
#include "ltlo/optim/bundle_adjust.h"
#include "ltlo/system/carried_stretch.h"
#include "ltlo/system/segmentation_writer.h"
#include "ltlo/tracking/dense_segmenter.h"
#include "ltlo/tracking/frame_builder.h"
#include "ltlo/tracking/oracle_mask_segmenter.h"
#include "ltlo/viewer/viewer.h"

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

/// The segmentation step the settings ask for (Seg.Enable, Seg.DenseInit), or the ground-truth
/// masks of the --oracle-masks ablation; its stages go to `timing`.
/// With a distorting lens each takes the images onto the ideal grid through `undistorter`.
std::unique_ptr<tracking::FrameSegmenter> makeSegmenter(const Settings& settings, bool oracle_masks, TimingStats* timing,
                                                        const std::shared_ptr<const Undistorter>& undistorter) {
  const SegmentationOptions& seg = settings.segmentation;
  if (oracle_masks) return std::make_unique<tracking::OracleMaskSegmenter>(seg.static_threshold, undistorter);
  if (!seg.enable) return std::make_unique<tracking::AllStaticSegmenter>(seg.static_threshold);
  if (seg.dense_init) {
    return std::make_unique<tracking::DenseSegmenter>(seg, settings.dense, settings.local_mapping,
                                                      settings.calib.camera.camera, timing, undistorter);
  }
  return std::make_unique<tracking::ClusterOnlySegmenter>(seg, settings.dense, settings.calib.camera.camera, timing,
                                                          undistorter);
}

}  // namespace

System::System(const Settings& settings, std::shared_ptr<const bow::Vocabulary> vocabulary,
               const SystemOptions& options)
    : settings_(settings), options_(options), vocabulary_(std::move(vocabulary)) {
  LTLO_ASSERT(vocabulary_ != nullptr && vocabulary_->numWords() > 0, "System needs a loaded vocabulary");
  use_imu_ = options_.use_imu && settings_.calib.has_imu;
  SensorCalib calib = settings_.calib;
  if (!use_imu_) calib.has_imu = false;  // frames are then built without preintegration

  atlas_ = std::make_unique<map::Atlas>(vocabulary_->numWords());
  builder_ = std::make_unique<tracking::FrameBuilder>(settings_.orb, calib);
  const std::vector<float> level_sigma2 = builder_->extractor().levelSigma2();

  tracking::TrackerOptions tracker_options;
  tracker_options.keyframe = settings_.keyframe;
  tracker_options.tracking = settings_.tracking;
  if (use_imu_ && settings_.imu_init.early_keyframes) {
    tracker_options.imu_init_keyframe_interval_s =
        settings_.imu_init.min_time_s / std::max(1, settings_.imu_init.min_keyframes - 1);
  }
  tracker_ = std::make_unique<tracking::Tracker>(*atlas_, tracker_options, level_sigma2);
  tracker_->setVocabulary(vocabulary_.get());
  tracker_->setSegmenter(makeSegmenter(settings_, options_.oracle_masks, &timing_, builder_->undistorter()));
  if (builder_->undistorter()->active()) {
    log::info("system: lens ", calib.camera.lens.describe(), "; keypoints undistorted by lookup, the dense images remapped (",
              static_cast<int>(builder_->undistorter()->idealCoverage() * 1000.0 + 0.5) / 10.0,
              " % of the ideal image has a raw source)");
  }
  tracker_->setLocalMappingCallback(
      [this](map::Map&, const std::shared_ptr<map::KeyFrame>& kf) { onNewKeyFrame(kf); });

  mapping::LocalMapperOptions mapper_options;
  mapper_options.local_mapping = settings_.local_mapping;
  mapper_options.segmentation = settings_.segmentation;
  mapper_options.vocabulary = vocabulary_;
  mapper_options.imu_init = settings_.imu_init;
  mapper_options.use_imu = use_imu_;
  mapper_options.refine_until_acceleration_sigma_m_s2 = settings_.tracking.acc_bias_sigma_m_s2;
  // Every RGB-D edge (tracking, local BA, fusion, loop and global BA): bf = fx * virtual baseline.
  mapper_options.bf_px_m = calib.camera.camera.fx() * settings_.tracking.virtual_baseline_m;
  mapper_ = std::make_unique<mapping::LocalMapper>(*atlas_, mapper_options, level_sigma2, &timing_);

  loop::LoopCloserOptions closer_options;
  closer_options.loop = settings_.loop;
  closer_options.rejoin_search = tracking::reacquireSearchOptions(tracker_options);
  closer_options.virtual_baseline_m = settings_.tracking.virtual_baseline_m;
  closer_options.min_point_beta = settings_.local_mapping.min_point_beta;
  closer_options.lambda_imu = settings_.local_mapping.lambda_imu;
  closer_options.visual_variance_estimation = settings_.local_mapping.visual_variance_estimation;
  loop::MappingControl mapping_control{[this] { mapper_->pause(); }, [this] { mapper_->resume(); },
                                       [this]() -> std::optional<Vec3> {
                                         const mapping::ImuState imu = mapper_->imuState();
                                         return imu.initialised ? std::optional<Vec3>(imu.g_w) : std::nullopt;
                                       }};
  if (use_imu_) {
    mapping_control.set_gravity_w = [this](const Vec3& g_w) { mapper_->setGravityFromFullBa(g_w); };
  }
  if (options_.threaded) {
    mapping_control.hold_tracking = [this] { world_gate_.beginChange(); };
    mapping_control.release_tracking = [this] { world_gate_.endChange(); };
  }
  closer_ = std::make_unique<loop::LoopCloser>(*atlas_, closer_options, std::move(mapping_control), &timing_);

  if (!options_.segmentation_dir.empty()) {
    segmentation_writer_ =
        std::make_unique<SegmentationWriter>(options_.segmentation_dir, 128, builder_->undistorter());
  }
  if (options_.threaded) {
    mapper_->setKeyFrameProcessedCallback([this](const std::shared_ptr<map::KeyFrame>& kf) {
      if (!loop_stopped_.load()) closer_->insertKeyFrame(kf);
    });
    // Started downstream first, so every receiver runs before anything is sent to it.
    loop_thread_ = std::thread([this] {
      log::setThreadName("loop");
      closer_->run();
      loop_stopped_.store(true);
      if (!finishing_.load()) log::error("loop closing stopped before shutdown (see the error above)");
    });
    mapping_thread_ = std::thread([this] {
      log::setThreadName("mapping");
      mapper_->run();
      mapping_stopped_.store(true);
      if (!finishing_.load()) log::error("local mapping stopped before shutdown (see the error above)");
    });
  }
  viewer::ViewerOutputs viewer_outputs;
  viewer_outputs.video_path = options_.viewer_video_path;
  viewer_outputs.png_dir = options_.viewer_png_dir;
  viewer_outputs.http_port = options_.viewer_http_port;
  viewer_outputs.http_bind = options_.viewer_http_bind;
  viewer_outputs.pose_stream = options_.viewer_pose_stream;
  if (viewer_outputs.any()) {
    try {
      viewer_ = std::make_unique<viewer::Viewer>(settings_.viewer, viewer_outputs,
                                                 [this](std::uint64_t map_id) { return viewerMap(map_id); });
    } catch (...) {
      shutdown();  // the workers started above are joined before the error leaves
      throw;
    }
  }
  log::info("system: ", options_.threaded ? "threaded" : "synchronous", ", ",
            use_imu_ ? "RGB-D-inertial" : "RGB-D only", ", segmentation ", tracker_->segmenter()->name(),
            ", vocabulary of ", vocabulary_->numWords(), " words");
}

System::~System() {
  try {
    shutdown();
  } catch (const std::exception& e) {
    log::error("system shutdown: ", e.what());
  }
}

void System::checkWorkers() const {
  if (!options_.threaded || finishing_.load()) return;
  if (mapping_stopped_.load()) throw SystemError("the local-mapping thread stopped on an error");
  if (loop_stopped_.load()) throw SystemError("the loop-closing thread stopped on an error");
}

void System::pollImuState() {
  if (!use_imu_) return;
  const mapping::ImuState imu = mapper_->imuState();
  if (!imu.initialised || imu.generation == imu_generation_) return;
  if (!tracker_->imuInitialised()) {
    log::info("IMU initialised: b_g = ", imu.bias.b_g.transpose(), ", b_a = ", imu.bias.b_a.transpose(),
              ", g_w = ", imu.g_w.transpose());
  }
  tracker_->setImuInitialised(imu.bias, imu.g_w, optim::accelerationSigma(imu.acceleration_covariance_w));
  imu_generation_ = imu.generation;
}

void System::onNewKeyFrame(const std::shared_ptr<map::KeyFrame>& kf) {
  if (current_input_ != nullptr) {
    std::vector<cv::Vec3b> colours = sampleColours(current_input_->color_bgr, kf->keypoints(), *builder_->undistorter());
    std::lock_guard<std::mutex> lock(records_mutex_);
    colours_[kf->id().value] = std::move(colours);
  }
  // Handed on after the frame's tracking section (trackFrame).
  pending_keyframes_.push_back(kf);
}

void System::processPendingKeyFrames() {
  while (!pending_keyframes_.empty()) {
    std::vector<std::shared_ptr<map::KeyFrame>> keyframes = std::move(pending_keyframes_);
    pending_keyframes_.clear();
    for (const std::shared_ptr<map::KeyFrame>& kf : keyframes) {
      mapper_->processKeyFrame(kf);
      if (!kf->isBad()) closer_->processKeyFrame(kf);
    }
  }
}

tracking::TrackingState System::trackFrame(const io::RgbdImuFrame& input) {
  if (shut_down_) throw std::logic_error("System::trackFrame after shutdown()");
  checkWorkers();
  const PinholeCamera& camera = builder_->calib().camera.camera;
  for (const cv::Mat* image : {&input.color_bgr, &input.depth_m}) {
    if (!image->empty() && (image->cols != camera.width() || image->rows != camera.height())) {
      throw InputError(image == &input.color_bgr ? input.color_path : input.depth_path, 0,
                       "image is " + std::to_string(image->cols) + "x" + std::to_string(image->rows) +
                           " but the calibration says " + std::to_string(camera.width()) + "x" +
                           std::to_string(camera.height()));
    }
  }
  ScopedTimer frame_timer(timing_, "tracking.frame");
  ScopedThreadCpuTimer frame_cpu_timer(timing_, "tracking.frame_cpu");
  pollImuState();

  // The segmenter starts on the images (possibly on its worker thread) while ORB is extracted here.
  tracking::FrameSegmenter& segmenter = *tracker_->segmenter();
  segmenter.begin(input);
  map::Frame frame = [&] {
    ScopedTimer timer(timing_, "tracking.orb");
    try {
      // The IMU interval follows the online time-offset estimate where the reader left room for it.
      const double shift_s = use_imu_ && input.imu_has_margin ? mapper_->timeShift() : 0.0;
      return builder_->build(input, tracker_->bias(), imu_shift_.next(shift_s));
    } catch (...) {
      segmenter.cancel();
      throw;
    }
  }();
  // BoW is computed by the tracker only where it is used: keyframes and relocalisation.

  tracking::TrackingState state = tracking::TrackingState::kNotInitialised;
  // From here until the record is stored, no correction or merge changes the world frame (the
  // frame's pose and its reference keyframe's stay in the same one).
  std::optional<TrackingSection> section(std::in_place, world_gate_);
  {
    ScopedTimer timer(timing_, "tracking.track");
    current_input_ = &input;
    try {
      state = tracker_->track(frame);
    } catch (...) {
      segmenter.cancel();
      current_input_ = nullptr;
      throw;
    }
    current_input_ = nullptr;
  }
  if (segmentation_writer_) {
    // Every frame's mask at the input resolution; encoded and written on the writer's thread.
    segmentation_writer_->push(SegmentationWriter::frameName(input.color_path, input.t_s),
                               frame.segmentation().dynamicMask(frame.staticThreshold(), camera.height(), camera.width()),
                               camera.width(), camera.height());
  }

  ++frames_;
  if (frame.hasPose()) {
    FrameRecord record;
    record.t_s = input.t_s;
    record.tracked = tracker_->frameTracked();
    const SE3 T_w_c = frame.T_w_c();
    record.T_w_c_online = T_w_c;
    if (std::shared_ptr<map::KeyFrame> reference = tracker_->referenceKeyFramePtr()) {
      record.map_online = reference->mapId();
      record.T_refb_c = map::latestPose_T_w_b(*reference).inverse() * T_w_c;
      record.reference = std::move(reference);
    } else {
      record.T_w_c = T_w_c;
    }
    if (record.tracked) ++frames_tracked_;
    const std::optional<SE3> predicted_T_w_b = tracker_->imuPredicted_T_w_b();
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
    const tracking::TrackingStats& stats = tracker_->stats();
    if (record.tracked && stats.inertial_link != 0 && stats.inliers < settings_.tracking.min_inliers) {
      ++frames_tracked_weak_imu_;
    }
    if (!record.tracked && stats.inertial_link != 0) ++frames_imu_predicted_;
    if (stats.relocalised) ++relocalisations_;
    if (stats.map_extended) ++maps_extended_;
    if (stats.reacquired) ++reacquisitions_;
    const bool tracked = record.tracked;
    const bool carried = record.carried;
    const map::MapId map_online = record.map_online;
    {
      std::lock_guard<std::mutex> lock(records_mutex_);
      records_.push_back(std::move(record));
    }
    if (viewer_) postToViewer(input, frame, state, tracked, carried, map_online);
  }
  section.reset();
  if (options_.threaded) {
    // Outside the section: a full queue may wait for local mapping, which a correction pauses.
    for (std::shared_ptr<map::KeyFrame>& kf : pending_keyframes_) {
      if (!mapping_stopped_.load()) mapper_->insertKeyFrame(std::move(kf));
    }
    pending_keyframes_.clear();
  }
  frame_timer.stop();
  frame_cpu_timer.stop();

  if (!options_.threaded) {
    processPendingKeyFrames();
    pollImuState();
  }
  return state;
}

void System::shutdown() {
  if (shut_down_) return;
  shut_down_ = true;
  finishing_.store(true);
  if (options_.threaded) {
    mapper_->requestFinish();
    if (mapping_thread_.joinable()) mapping_thread_.join();
    closer_->requestFinish();
    if (loop_thread_.joinable()) loop_thread_.join();
  } else {
    closer_->waitForGlobalBa();
  }
  // The tracking stage's own worker thread (depth clusters, pyramid) ends with the run.
  if (tracking::FrameSegmenter* segmenter = tracker_->segmenter()) segmenter->finish();
  if (segmentation_writer_) {
    const int written = segmentation_writer_->finish();
    log::info("system: ", written, " segmentation masks written to ", options_.segmentation_dir);
  }
  // Last: its final picture shows the map after the last correction.
  if (viewer_) viewer_->stop();
  log::info("system shut down: ", frames_, " frames, ", closer_->numLoops(), " loops, ", closer_->numMerges(),
            " merges, ", atlas_->numMaps(), " map(s)");
}

std::unordered_map<map::MapId, map::MapId> System::floatingMaps(const std::vector<FrameRecord>& records) const {
  std::unordered_map<map::MapId, MapFrameSpan> maps;
  for (const FrameRecord& record : records) {
    if (!record.reference) continue;
    const auto [it, inserted] = maps.try_emplace(record.reference->mapId());
    if (inserted) it->second.first_t_s = record.t_s;
    it->second.last_t_s = record.t_s;
  }
  for (auto& [id, span] : maps) {
    map::Map* map = atlas_->map(id);
    const std::optional<map::MapOrigin> origin = map != nullptr ? map->origin() : std::nullopt;
    if (origin) span.origin_parent = atlas_->resolve(origin->parent);
  }
  return floatingMapWorlds(maps, kFloatingMapMaxSpan_s, kFloatingMapMaxDepth);
}

std::vector<FramePose> System::trajectory(bool smooth_carried_frames) const {
  std::vector<FrameRecord> records;
  {
    std::lock_guard<std::mutex> lock(records_mutex_);
    records = records_;
  }
  // Short maps started at the IMU's prediction and never merged: their coordinates are their
  // parent's world as the dead reckoning placed them, so their frames belong to the carried
  // stretch around them, and a frame anchored after it in that world ends it.
  const std::unordered_map<map::MapId, map::MapId> floating = floatingMaps(records);
  auto world_of = [&floating](map::MapId id) {
    const auto it = floating.find(id);
    return it == floating.end() ? id : it->second;
  };
  // Keyframe poses are read outside records_mutex_ (it is a leaf lock).
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
    poses.push_back(pose);
    samples.push_back(std::move(sample));
  }
  if (smooth_carried_frames) {
    smoothCarriedStretches(samples, settings_.tracking.carried_velocity_sigma_m_s,
                           settings_.tracking.acc_bias_sigma_m_s2);
    for (std::size_t i = 0; i < poses.size(); ++i) poses[i].T_w_c = samples[i].T_w_c;
  }
  return poses;
}

void System::postToViewer(const io::RgbdImuFrame& input, const map::Frame& frame, tracking::TrackingState state,
                          bool tracked, bool carried, map::MapId map) {
  viewer_->postPose(frames_ - 1, input.t_s, frame.T_w_c(), tracked, map.value);
  const int events = closer_->numLoops() + closer_->numMerges();
  if (events != viewer_events_seen_) {
    viewer_events_seen_ = events;
    viewer_->notifyLoop();
  }
  if (!viewer_->due(input.t_s)) return;
  ScopedTimer timer(timing_, "tracking.viewer_post");
  viewer::ViewerFrame view;
  view.index = frames_ - 1;
  view.t_s = input.t_s;
  view.color_bgr = input.color_bgr.clone();
  const PinholeCamera& camera = builder_->calib().camera.camera;
  view.dynamic_mask = frame.segmentation().dynamicMask(frame.staticThreshold(), camera.height() / 4, camera.width() / 4);
  // The picture shows the raw image: with a distorting lens the mask (ideal grid) and the keypoints
  // (ideal pixels) are taken back through the lens, as the segmentation writer does for its masks.
  const Undistorter& undistorter = *builder_->undistorter();
  if (undistorter.active() && !view.dynamic_mask.empty()) {
    if (viewer_raw_to_ideal_.size() != view.dynamic_mask.size()) {
      const int scale = std::max(1, camera.width() / view.dynamic_mask.cols);
      cv::resize(undistorter.rawToIdealMap(scale), viewer_raw_to_ideal_, view.dynamic_mask.size(), 0.0, 0.0,
                 cv::INTER_AREA);
    }
    cv::Mat raw_mask;
    cv::remap(view.dynamic_mask, raw_mask, viewer_raw_to_ideal_, cv::noArray(), cv::INTER_NEAREST,
              cv::BORDER_REPLICATE);
    view.dynamic_mask = raw_mask;
  }
  const std::vector<features::Keypoint>& keypoints = frame.keypoints();
  view.keypoints.reserve(keypoints.size());
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    viewer::ViewerKeypoint kp;
    Vec2 u(keypoints[i].x_px, keypoints[i].y_px);
    if (undistorter.active()) u = undistorter.model().distortPixel(u);
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
  view.map = map.value;
  view.state = tracking::trackingStateName(state);
  view.imu_carried = carried;
  view.tracked = tracked;
  viewer_->post(std::move(view));
}

viewer::ViewerMap System::viewerMap(std::uint64_t map_id) const {
  viewer::ViewerMap view;
  const map::MapId resolved = atlas_->resolve(map::MapId(map_id));
  view.map = resolved.value;
  const std::vector<map::MapId> map_ids = atlas_->mapIds();
  view.maps = static_cast<int>(map_ids.size());
  for (const map::MapId id : map_ids) {
    if (const map::Map* map = atlas_->map(id)) view.keyframes_all_maps += static_cast<int>(map->numKeyFrames());
  }
  view.loops = closer_->numLoops();
  view.merges = closer_->numMerges();
  map::Map* map = atlas_->map(resolved);
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
  // The frames so far, from their reference keyframes' latest poses (loop corrections move them);
  // the records are copied under their leaf lock, the keyframes read after it.
  std::vector<std::pair<std::shared_ptr<const map::KeyFrame>, SE3>> references;
  {
    std::lock_guard<std::mutex> lock(records_mutex_);
    references.reserve(records_.size());
    for (const FrameRecord& record : records_) {
      if (record.reference) references.emplace_back(record.reference, record.T_refb_c);
    }
  }
  view.trajectory_w.reserve(references.size());
  for (const auto& [reference, T_refb_c] : references) {
    if (reference->mapId() != resolved) continue;
    view.trajectory_w.push_back((map::latestPose_T_w_b(*reference) * T_refb_c).translation().cast<float>());
  }
  return view;
}

std::vector<FramePose> System::onlineTrajectory() const {
  std::lock_guard<std::mutex> lock(records_mutex_);
  std::vector<FramePose> poses;
  poses.reserve(records_.size());
  for (const FrameRecord& record : records_) {
    FramePose pose;
    pose.t_s = record.t_s;
    pose.T_w_c = record.T_w_c_online;
    pose.tracked = record.tracked;
    pose.map = record.map_online;
    poses.push_back(pose);
  }
  return poses;
}

std::vector<KeyFrameRecord> System::keyFrames() const {
  std::vector<KeyFrameRecord> keyframes;
  for (const map::MapId map_id : atlas_->mapIds()) {
    const map::Map* map = atlas_->map(map_id);
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

std::vector<MapPointRecord> System::mapPoints() const {
  struct PointSource {
    MapPointRecord record;
    std::vector<std::pair<std::uint64_t, int>> observations;  // reference keyframe first
  };
  std::vector<PointSource> sources;
  for (const std::shared_ptr<map::MapPoint>& point : atlas_->activeMap().mapPoints()) {
    if (point->isBad()) continue;
    PointSource source;
    source.record.p_w = point->p_w();
    source.record.beta = point->beta();
    const map::KeyFrameId reference = point->referenceKeyFrame();
    if (const std::optional<int> index = point->indexIn(reference)) {
      source.observations.emplace_back(reference.value, *index);
    }
    for (const auto& [kf, index] : point->observations()) source.observations.emplace_back(kf.value, index);
    sources.push_back(std::move(source));
  }
  std::vector<MapPointRecord> points;
  points.reserve(sources.size());
  std::lock_guard<std::mutex> lock(records_mutex_);
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

SystemCounts System::counts() const {
  SystemCounts counts;
  counts.frames = frames_;
  {
    std::lock_guard<std::mutex> lock(records_mutex_);
    counts.frames_with_pose = static_cast<int>(records_.size());
  }
  counts.frames_tracked = frames_tracked_;
  const std::vector<map::MapId> map_ids = atlas_->mapIds();
  counts.maps = static_cast<int>(map_ids.size());
  counts.maps_created = tracker_->numMapsCreated();
  counts.frames_tracked_weak_imu = frames_tracked_weak_imu_;
  counts.frames_imu_predicted = frames_imu_predicted_;
  counts.relocalisations = relocalisations_;
  counts.maps_extended = maps_extended_;
  counts.reacquisitions = reacquisitions_;
  counts.loops = closer_->numLoops();
  counts.merges = closer_->numMerges();
  for (const map::MapId map_id : map_ids) {
    if (const map::Map* map = atlas_->map(map_id)) {
      counts.keyframes += static_cast<int>(map->numKeyFrames());
      counts.map_points += static_cast<int>(map->numMapPoints());
    }
  }
  counts.imu_initialised = tracker_->imuInitialised();
  return counts;
}

RunReport System::report(double wall_s) const {
  RunReport report;
  report.trajectory = trajectory();
  report.trajectory_online = onlineTrajectory();
  report.keyframes = keyFrames();
  report.map_points = mapPoints();
  report.counts = counts();
  report.timing = timing_.stages();
  report.wall_s = wall_s;
  report.peak_memory_mb = peakMemoryMb();
  report.oracle_masks = options_.oracle_masks;
  const mapping::TimeOffsetStatus offset = mapper_->timeOffset();
  report.time_offset_estimated = offset.estimated;
  report.time_offset_s = settings_.calib.imu.time_offset_s + offset.shift_s;
  report.time_offset_sigma_s = offset.sigma_s;
  report.time_offset_updates = offset.updates;
  if (viewer_) {
    const viewer::ViewerCounts viewer = viewer_->counts();
    report.viewer_on = true;
    report.viewer_rendered = viewer.rendered;
    report.viewer_dropped = viewer.dropped;
    report.viewer_video_frames = viewer.video_frames;
    report.viewer_png_frames = viewer.png_frames;
    report.viewer_http_frames = viewer.http_frames;
    report.viewer_poses = viewer.poses;
  }
  return report;
}

tracking::TrackingState System::state() const { return tracker_->state(); }

}  // namespace ltlo::system
