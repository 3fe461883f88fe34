#include "ltlo/system/system.h"

#include <chrono>
#include <optional>
#include <stdexcept>
#include <utility>

#include "bow/vocabulary.h"
#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/core/process_memory.h"
#include "ltlo/core/undistorter.h"
#include "ltlo/loop/loop_closer.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/atlas_file.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/mapping/local_mapper.h"
#include "ltlo/optim/bundle_adjust.h"
#include "ltlo/system/run_recorder.h"
#include "ltlo/system/segmentation_writer.h"
#include "ltlo/tracking/frame_builder.h"
#include "stage_options.h"
#include "viewer_feed.h"

namespace ltlo::system {

System::System(const Settings& settings, std::shared_ptr<const bow::Vocabulary> vocabulary,
               const SystemOptions& options)
    : settings_(settings), options_(options), vocabulary_(std::move(vocabulary)) {
  LTLO_ASSERT(vocabulary_ != nullptr && vocabulary_->numWords() > 0, "System needs a loaded vocabulary");
  use_imu_ = options_.use_imu && settings_.calib.has_imu;
  SensorCalib calib = settings_.calib;
  if (!use_imu_) calib.has_imu = false;  // frames are then built without preintegration

  builder_ = std::make_unique<tracking::FrameBuilder>(settings_.orb, calib);
  std::optional<map::AtlasImuState> loaded_imu;
  if (options_.resume && options_.load_atlas_path.empty()) {
    throw ConfigError("resuming a run needs the atlas file it saved (--load-atlas FILE)");
  }
  if (options_.load_atlas_path.empty()) {
    if (settings_.tracking.localisation_only) {
      throw ConfigError(settings_.config_path + ": Tracking.LocalisationOnly = 1 needs an atlas to localise in (--load-atlas FILE)");
    }
    atlas_ = std::make_unique<map::Atlas>(vocabulary_->numWords());
  } else {
    loaded_imu = loadAtlas();
  }
  recorder_ = std::make_unique<RunRecorder>(*atlas_, settings_.tracking);
  const std::vector<float> level_sigma2 = builder_->extractor().levelSigma2();

  tracking::TrackerOptions tracker_options = trackerOptions(settings_, use_imu_);
  // A resumed run is not lost in the loaded maps: its tracker's state comes from the file.
  tracker_options.start_in_loaded_atlas = loaded_imu.has_value() && !options_.resume;
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

  mapper_ = std::make_unique<mapping::LocalMapper>(
      *atlas_, localMapperOptions(settings_, calib, vocabulary_, use_imu_), level_sigma2, &timing_);
  if (use_imu_ && loaded_imu && loaded_imu->initialised && !options_.resume) {
    // Gravity is the loaded world's, the biases those of the same sensor: this run refines them.
    mapper_->seedImuState(loaded_imu->bias, loaded_imu->g_w, loaded_imu->acceleration_covariance_w);
  }

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
  closer_ = std::make_unique<loop::LoopCloser>(*atlas_, loopCloserOptions(settings_, tracker_options, use_imu_),
                                               std::move(mapping_control), &timing_);

  if (options_.resume) restoreRunState();  // before any thread sees the stages
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
  const viewer::ViewerOutputs viewer_outputs = ViewerFeed::outputs(options_);
  if (viewer_outputs.any()) {
    try {
      viewer_ = std::make_unique<ViewerFeed>(settings_.viewer, viewer_outputs,
                                             [this](std::uint64_t map_id) { return viewerMap(map_id); }, *closer_,
                                             builder_->calib().camera.camera, *builder_->undistorter(), timing_);
    } catch (...) {
      shutdown(false);  // the workers started above are joined before the error leaves
      throw;
    }
  }
  log::info("system: ", options_.threaded ? "threaded" : "synchronous", ", ",
            use_imu_ ? "RGB-D-inertial" : "RGB-D only", ", segmentation ", tracker_->segmenter()->name(),
            ", vocabulary of ", vocabulary_->numWords(), " words");
}

System::~System() {
  try {
    shutdown(false);
  } catch (const std::exception& e) {
    log::error("system shutdown: ", e.what());
  }
  // The viewer thread reads the run's records and the map (viewerMap): it ends before any member
  // goes, also when shutdown() stopped on an error before it reached the viewer.
  viewer_.reset();
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
  tracker_->setImuInitialised(imu.bias, imu.g_w, optim::accelerationSigma(imu.acceleration_covariance_w),
                              imu.awaiting_own_initialisation);
  imu_generation_ = imu.generation;
}

void System::onNewKeyFrame(const std::shared_ptr<map::KeyFrame>& kf) {
  if (current_input_ != nullptr) {
    recorder_->recordKeyFrameColours(*kf, current_input_->color_bgr, *builder_->undistorter());
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
  if (resume_point_ && resume_point_->previous_frame_t_s && loaded_run_) {
    throw std::logic_error("System::trackFrame of a resumed run before restorePreviousFrame()");
  }
  ScopedTimer frame_timer(timing_, "tracking.frame");
  ScopedThreadCpuTimer frame_cpu_timer(timing_, "tracking.frame_cpu");
  frame_in_progress_ = true;  // an exception from here on leaves the stages mid-frame
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

  if (const std::optional<RecordedFrame> recorded = recorder_->recordFrame(input.t_s, frame, *tracker_)) {
    if (viewer_) viewer_->post(recorder_->numFrames() - 1, input, frame, state, *recorded);
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
  last_input_ = std::make_pair(input.index, input.t_s);
  frame_in_progress_ = false;
  return state;
}

void System::shutdown(bool run_finished) {
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
  if (run_finished) {
    ScopedTimer timer(timing_, "system.final_ba");
    closer_->finalGlobalBa();
  }
  // The tracking stage's own worker thread (depth clusters, pyramid) ends with the run.
  if (tracking::FrameSegmenter* segmenter = tracker_->segmenter()) segmenter->finish();
  if (segmentation_writer_) {
    const int written = segmentation_writer_->finish();
    log::info("system: ", written, " segmentation masks written to ", options_.segmentation_dir);
  }
  // The stages have let go: the culled keyframes the records still hold whole are swapped now.
  recorder_->releaseCulledKeyFrames();
  // Last: its final picture shows the map after the last correction.
  if (viewer_) viewer_->stop();
  const SystemCounts counts = recorder_->counts(*tracker_, *closer_);
  log::info("system shut down: ", recorder_->numFrames(), " frames, ", closer_->numLoops(), " loops, ",
            closer_->numMerges(), " merges, ", atlas_->numMaps(), " map(s), ", counts.keyframes, " keyframes (",
            counts.keyframes_released, " culled ones held by the frame records without their image data)");
}

std::vector<FramePose> System::trajectory() const {
  const TrackingOptions& tracking = settings_.tracking;
  return trajectory(!tracking.smooth_carried_frames ? CarriedCorrection::kNone
                    : tracking.carried_bridge       ? CarriedCorrection::kBridge
                                                    : CarriedCorrection::kBlend);
}

std::vector<FramePose> System::trajectory(CarriedCorrection correction) const {
  return recorder_->trajectory(correction);
}

viewer::ViewerMap System::viewerMap(std::uint64_t map_id) const {
  return viewerMapOf(*atlas_, *closer_, *recorder_, map_id);
}

std::vector<FramePose> System::onlineTrajectory() const { return recorder_->onlineTrajectory(); }

std::vector<KeyFrameRecord> System::keyFrames() const { return recorder_->keyFrames(); }

std::vector<MapPointRecord> System::mapPoints() const { return recorder_->mapPoints(); }

SystemCounts System::counts() const {
  SystemCounts counts = recorder_->counts(*tracker_, *closer_);
  counts.atlas_loaded = loaded_.atlas_loaded;
  counts.keyframes_loaded = loaded_.keyframes_loaded;
  counts.map_points_loaded = loaded_.map_points_loaded;
  counts.first_pose_t_s = recorder_->firstPoseTime();
  return counts;
}

map::AtlasBuildInfo System::atlasBuildInfo() const {
  return map::makeAtlasBuildInfo(*vocabulary_,
                                 map::mapSettingsSummary(builder_->calib(), settings_.orb.num_levels,
                                                         settings_.orb.scale_factor),
                                 "LTLO-SLAM, settings " + settings_.config_path);
}

map::AtlasImuState System::loadAtlas() {
  const std::string& path = options_.load_atlas_path;
  const auto start = std::chrono::steady_clock::now();
  map::LoadedAtlas loaded = map::loadAtlas(path, atlasBuildInfo(), *vocabulary_, options_.resume);
  const double load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  atlas_ = std::move(loaded.atlas);
  loaded_.atlas_loaded = true;
  loaded_run_ = std::move(loaded.run);
  if (settings_.loop.hold_loaded_map && !options_.resume) {
    // Before any other thread sees them (Loop.HoldLoadedMap).
    for (const map::MapId id : atlas_->mapIds()) {
      for (const std::shared_ptr<map::KeyFrame>& kf : atlas_->map(id)->keyFrames()) kf->markAnchor();
    }
  }
  for (const map::AtlasFileSummary::MapSummary& m : loaded.summary.maps) {
    loaded_.keyframes_loaded += static_cast<int>(m.keyframes);
    loaded_.map_points_loaded += static_cast<int>(m.map_points);
  }
  log::info("system: atlas ", path, " loaded: ", loaded.summary.maps.size(), " map(s), ", loaded_.keyframes_loaded,
            " keyframes, ", loaded_.map_points_loaded, " map points in ", load_s, " s (built with ", loaded.build.built_with, "); IMU ",
            loaded.imu.initialised ? "initialised" : "not initialised", settings_.tracking.localisation_only
            ? "; localisation only" : "", options_.resume ? "; resuming its run" : "");
  return loaded.imu;
}

RunStages System::runStages() {
  return RunStages{*tracker_, tracker_->segmenter(), *mapper_, *closer_, *recorder_, imu_shift_, imu_generation_};
}

std::uint64_t System::settingsFingerprint() const {
  return runStateFingerprint(settings_.describe(), use_imu_, options_.oracle_masks);
}

void System::restoreRunState() {
  LTLO_ASSERT(loaded_run_.has_value(), "restoreRunState without a loaded run state");
  const std::uint64_t fingerprint = readRunState(*loaded_run_, runStages());
  ResumePoint point;
  point.next_frame_index = loaded_run_->header.next_frame_index;
  point.last_frame_t_s = loaded_run_->header.last_frame_t_s;
  if (tracking::FrameSegmenter* segmenter = tracker_->segmenter()) {
    point.previous_frame_t_s = segmenter->previousFrameTime();
    point.kept_frame_t_s = segmenter->keptFrameTimes();
  }
  point.settings_differ = fingerprint != settingsFingerprint();
  if (point.settings_differ) {
    log::warn("system: the atlas's run was saved with other settings than this run's: the resumed run is not its "
              "exact continuation");
  }
  log::info("system: resuming the saved run at frame ", point.next_frame_index, " (its last frame at t = ",
            point.last_frame_t_s, " s), tracking ", tracking::trackingStateName(tracker_->state()));
  resume_point_ = point;
  if (!point.previous_frame_t_s) loaded_run_.reset();
}

void System::restoreKeptFrame(const io::RgbdImuFrame& frame) {
  if (!resume_point_ || !loaded_run_ || tracker_->segmenter()->keptFrameTimes().empty()) {
    throw std::logic_error("System::restoreKeptFrame: no resumed run waits for a kept frame");
  }
  tracker_->segmenter()->restoreKeptFrame(frame);
}

void System::restorePreviousFrame(const io::RgbdImuFrame& previous) {
  if (!resume_point_ || !resume_point_->previous_frame_t_s || !loaded_run_) {
    throw std::logic_error("System::restorePreviousFrame: no resumed run waits for its previous frame");
  }
  if (!tracker_->segmenter()->keptFrameTimes().empty()) {
    throw std::logic_error("System::restorePreviousFrame before restoreKeptFrame of every kept frame");
  }
  tracker_->segmenter()->restorePreviousFrame(previous);
  loaded_run_.reset();
}

void System::saveAtlas(const std::string& path) {
  if (!shut_down_) throw std::logic_error("System::saveAtlas before shutdown()");
  const mapping::ImuState imu = mapper_->imuState();
  map::AtlasImuState state;
  state.initialised = use_imu_ && imu.initialised;
  state.bias = imu.bias;
  state.g_w = imu.g_w;
  state.acceleration_covariance_w = imu.acceleration_covariance_w;
  state.time_offset_s = settings_.calib.imu.time_offset_s + mapper_->timeOffset().shift_s;
  // The run state, unless a stage stopped part-way (an error inside a frame, local mapping or loop
  // closing stopped with keyframes queued): the maps are saved all the same.
  if (frame_in_progress_ || mapper_->queuedKeyFrames() > 0 || closer_->queuedKeyFrames() > 0 ||
      closer_->globalBaRunning()) {
    map::saveAtlas(*atlas_, state, atlasBuildInfo(), path);
    log::warn("system: atlas saved to ", path, " without the run state (the run stopped part-way through a ",
              frame_in_progress_ ? "frame" : "keyframe", "): it loads, but cannot be resumed");
    return;
  }
  // The next frame follows the last one tracked (or, a resumed run that tracked none, the frame it
  // would have resumed at).
  map::RunStateHeader header;
  if (last_input_) {
    header.next_frame_index = static_cast<std::uint64_t>(last_input_->first) + 1;
    header.last_frame_t_s = last_input_->second;
  } else if (resume_point_) {
    header.next_frame_index = resume_point_->next_frame_index;
    header.last_frame_t_s = resume_point_->last_frame_t_s;
  }
  const std::string run_state = writeRunState(*atlas_, header, settingsFingerprint(), runStages());
  map::saveAtlas(*atlas_, state, atlasBuildInfo(), path, &run_state);
  const SystemCounts c = counts();
  log::info("system: atlas saved to ", path, ": ", c.maps, " map(s), ", c.keyframes, " keyframes, ", c.map_points,
            " map points");
}

RunReport System::report(double wall_s) const {
  RunReport report;
  report.trajectory = trajectory();
  report.trajectory_online = onlineTrajectory();
  report.keyframes = keyFrames();
  report.map_points = mapPoints();
  report.map_points_map = atlas_->activeMapId();
  report.counts = counts();
  report.timing = timing_.stages();
  report.mapping_timeline = mapper_->timeline();
  report.wall_s = wall_s;
  report.peak_memory_mb = peakResidentMb();
  report.oracle_masks = options_.oracle_masks;
  const mapping::TimeOffsetStatus offset = mapper_->timeOffset();
  report.time_offset_estimated = offset.estimated;
  report.time_offset_s = settings_.calib.imu.time_offset_s + offset.shift_s;
  report.time_offset_sigma_s = offset.sigma_s;
  report.time_offset_updates = offset.updates;
  if (viewer_) viewer_->addCounts(report);
  return report;
}

tracking::TrackingState System::state() const { return tracker_->state(); }

mapping::ImuState System::imuState() const { return mapper_->imuState(); }

}  // namespace ltlo::system
