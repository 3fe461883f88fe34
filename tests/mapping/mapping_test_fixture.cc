#include "mapping_test_fixture.h"

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "ltlo/core/blocking_queue.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/map/atlas.h"
#include "ltlo/sim/simulator.h"
#include "ltlo/tracking/frame_builder.h"
#include "ltlo/tracking/tracker.h"

namespace ltlo::mapping::test {

namespace fs = std::filesystem;

namespace {

fs::path* g_dir = nullptr;

OrbOptions orbOptions() {
  OrbOptions orb;
  orb.num_features = 500;
  return orb;
}

struct Truth {
  io::Trajectory T_w_c;
  SE3 T_b_c;
  std::vector<std::pair<double, imu::ImuBias>> biases;
};
Truth* g_truth = nullptr;

std::vector<std::pair<double, imu::ImuBias>> readBiases(const std::string& path) {
  std::vector<std::pair<double, imu::ImuBias>> biases;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double t_s = 0.0;
    imu::ImuBias bias;
    fields >> t_s >> bias.b_g.x() >> bias.b_g.y() >> bias.b_g.z() >> bias.b_a.x() >> bias.b_a.y() >> bias.b_a.z();
    if (fields) biases.emplace_back(t_s, bias);
  }
  return biases;
}

/// A keyframe at least every 0.5 s (the default 1 s gives ~1 keyframe/s on these sequences).
tracking::TrackerOptions trackerOptions() {
  tracking::TrackerOptions options;
  options.keyframe.max_interval_s = 0.5;
  return options;
}

}  // namespace

double angleDeg(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI; }

void MappingOnSimulatedSequence::SetUpTestSuite() {
  if (g_dir != nullptr) return;
  g_dir = new fs::path(fs::temp_directory_path() / ("ltlo_mapping_" + std::to_string(::getpid())));
  sim::SimOptions options;
  options.width_px = 320;
  options.height_px = 240;
  options.scenario = sim::Scenario::kStatic;
  options.seed = 5;
  options.duration_s = 6.0;
  sim::writeSequence(options, g_dir->string(), 0);
  io::SequenceReader reader = io::SequenceReader::open(g_dir->string());
  g_truth = new Truth{reader.groundTruth(), reader.calib().imu.T_b_c, readBiases((*g_dir / "imu_biases.txt").string())};
}

void MappingOnSimulatedSequence::TearDownTestSuite() {
  if (g_dir == nullptr) return;
  fs::remove_all(*g_dir);
  delete g_dir;
  delete g_truth;
  g_dir = nullptr;
  g_truth = nullptr;
}

LocalMapperOptions MappingOnSimulatedSequence::mapperOptions(bool use_imu) {
  LocalMapperOptions options;
  options.use_imu = use_imu;
  // bf = fx * virtual baseline of the 320x240 test camera, as System wires it.
  sim::SimOptions camera;
  camera.width_px = 320;
  camera.height_px = 240;
  options.bf_px_m = camera.camera().fx() * trackerOptions().tracking.virtual_baseline_m;
  options.imu_init.min_keyframes = 6;
  options.imu_init.min_time_s = 2.0;
  options.imu_refinement_delays_s = {1.5, 3.0};
  options.imu_init.refine_interval_s = 0.0;  // the two scheduled refinements only (ImuInit.RefineInterval off)
  return options;
}

Vec3 MappingOnSimulatedSequence::trueVelocity(double t_s) {
  const io::Trajectory& gt = g_truth->T_w_c;
  std::size_t k = 1;
  while (k + 1 < gt.size() && gt[k].t_s < t_s - 1e-6) ++k;
  k = std::min(k, gt.size() - 2);
  const SE3 T_c_b = g_truth->T_b_c.inverse();
  const Vec3 p_before = (gt[k - 1].T_w_x * T_c_b).translation();
  const Vec3 p_after = (gt[k + 1].T_w_x * T_c_b).translation();
  return (p_after - p_before) / (gt[k + 1].t_s - gt[k - 1].t_s);
}

imu::ImuBias MappingOnSimulatedSequence::trueBias(double t_s) {
  const auto& biases = g_truth->biases;
  if (biases.empty()) return imu::ImuBias();
  std::size_t k = 0;
  while (k + 1 < biases.size() && biases[k].first < t_s) ++k;
  return biases[k].second;
}

RunResult MappingOnSimulatedSequence::run(const RunConfig& config) {
  io::SequenceReader reader = io::SequenceReader::open(g_dir->string());
  const tracking::FrameBuilder builder(orbOptions(), reader.calib());
  map::Atlas atlas(16);
  map::Map& map = atlas.activeMap();
  tracking::Tracker tracker(atlas, trackerOptions(), builder.extractor().levelSigma2());
  TimingStats timing;
  LocalMapper mapper(atlas, config.options, builder.extractor().levelSigma2(), &timing);
  RunResult result;

  // Threaded: the mapper in its own thread; a third thread pauses it right after keyframes are
  // inserted (while it is likely processing one: the pause aborts its BA and waits for the end of
  // the keyframe, as for loop closing) and counts keyframes processed while it held the pause.
  std::atomic<bool> paused{false};
  std::atomic<int> processed_while_paused{0};
  BlockingQueue<int> inserted_events(4096);
  mapper.setKeyFrameProcessedCallback([&](const std::shared_ptr<map::KeyFrame>&) {
    if (paused.load()) processed_while_paused.fetch_add(1);
  });
  std::thread mapping_thread;
  std::thread pausing_thread;
  int pauses = 0;
  if (config.threaded) {
    mapping_thread = std::thread([&] { mapper.run(); });
    pausing_thread = std::thread([&] {
      while (inserted_events.pop()) {
        if (pauses >= config.pause_rounds) continue;
        mapper.pause();
        paused.store(true);
        // What loop closing does while the mapper holds: read the map.
        double sum = 0.0;
        for (const auto& kf : map.keyFrames()) sum += kf->T_w_b().translation().norm();
        EXPECT_TRUE(std::isfinite(sum));
        paused.store(false);
        mapper.resume();
        ++pauses;
      }
    });
  }
  if (config.with_mapper) {
    tracker.setLocalMappingCallback([&](map::Map&, const std::shared_ptr<map::KeyFrame>& kf) {
      if (config.threaded) {
        mapper.insertKeyFrame(kf);
        inserted_events.tryPush(1);
      } else {
        mapper.processKeyFrame(kf);
      }
    });
  }

  io::Trajectory estimate;
  while (auto input = reader.next()) {
    map::Frame frame = builder.build(*input);
    if (result.frames == 0) frame.setPose_T_w_c(reader.groundTruth().front().T_w_x);
    const tracking::TrackingState state = tracker.track(frame);
    ++result.frames;
    if (result.imu_initialised_at_s < 0.0 && mapper.imuState().initialised) result.imu_initialised_at_s = frame.t_s();
    if (state != tracking::TrackingState::kOk) continue;
    ++result.ok;
    estimate.push_back({frame.t_s(), tracker.T_w_c()});
  }
  if (config.threaded) {
    mapper.requestFinish();
    mapping_thread.join();
    inserted_events.close();
    pausing_thread.join();
    EXPECT_TRUE(mapper.finished());
  }

  result.keyframes_created = tracker.numKeyFrames();
  result.counters = mapper.counters();
  result.imu = mapper.imuState();
  result.pauses = pauses;
  result.processed_while_paused = processed_while_paused.load();
  result.ate = eval::computeAte(eval::associateTrajectories(reader.groundTruth(), estimate), false);
  io::Trajectory keyframe_poses;
  for (const auto& kf : map.keyFrames()) {
    keyframe_poses.push_back({kf->t_s(), kf->T_w_c()});
    result.velocities.push_back({kf->t_s(), kf->v_w_b()});
  }
  std::sort(keyframe_poses.begin(), keyframe_poses.end(),
            [](const io::StampedPose& a, const io::StampedPose& b) { return a.t_s < b.t_s; });
  std::sort(result.velocities.begin(), result.velocities.end(),
            [](const KeyFrameVelocity& a, const KeyFrameVelocity& b) { return a.t_s < b.t_s; });
  result.keyframe_ate = eval::computeAte(eval::associateTrajectories(reader.groundTruth(), keyframe_poses), false);
  result.keyframes_in_map = static_cast<int>(map.numKeyFrames());
  result.points_in_map = static_cast<int>(map.numMapPoints());
  const StageTiming keyframe_timing = timing.stage("mapping.keyframe");
  const StageTiming ba_timing = timing.stage("mapping.local_ba");
  result.mapping_mean_ms = keyframe_timing.count > 0 ? 1e3 * keyframe_timing.total_s / keyframe_timing.count : 0.0;
  result.mapping_max_ms = 1e3 * keyframe_timing.max_s;
  result.local_ba_mean_ms = ba_timing.count > 0 ? 1e3 * ba_timing.total_s / ba_timing.count : 0.0;
  return result;
}

}  // namespace ltlo::mapping::test
