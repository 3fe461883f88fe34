// Standstill end to end (issue 32), System on short generated 320x240 sequences at 15 Hz,
// synchronous (deterministic), with config_yaml/synthetic.yaml's zero-velocity update and IMU
// initialisation from rest:
//   - a still start initialises the IMU from rest within its first 2.7 s: gravity within 0.5 deg of
//     the truth, the gyro bias within its sigma (rms of IMU.NoiseGyro / sqrt(ImuInit.RestTime) per
//     axis) of the simulator's true bias;
//   - a 3 s standstill while a box crosses the view keeps the pose within 3 mm and makes no keyframe.
//   - a start whose view is too poor for a map (blank images) is carried by the IMU's dead reckoning
//     (Tracking.PreMapImuPose): every frame has a pose, and the map starts where the robot is;
//   - the map started after that wait initialises the IMU from the rest before it within 1 s
//     (ImuInit.FromPreMapRest): gravity within 0.5 deg, the gyro bias within 3 sigma of the rest's.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "end_to_end_suite.h"
#include "ltlo/core/log.h"
#include "ltlo/core/settings.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/sim/simulator.h"
#include "ltlo/system/run_outputs.h"
#include "ltlo/system/system.h"

namespace ltlo::system {
namespace {

namespace fs = std::filesystem;
using test_support::EndToEndSuite;
using test_support::shortRunSettings;
using test_support::shortRunSimOptions;
using test_support::truthNearest;

double angleDeg(const Vec3& a, const Vec3& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

// The true gyro bias at t_s from imu_biases.txt ("t bgx bgy bgz bax bay baz").
Vec3 trueGyroBias(const std::string& dir, double t_s) {
  std::ifstream in(dir + "/imu_biases.txt");
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double t = 0.0;
    Vec3 b_g;
    fields >> t >> b_g.x() >> b_g.y() >> b_g.z();
    if (t >= t_s) return b_g;
  }
  ADD_FAILURE() << "no true bias at " << t_s << " s in " << dir;
  return Vec3::Zero();
}

class StandstillEndToEnd : public EndToEndSuite {
 public:
  static void SetUpTestSuite() { createSuiteResources("ltlo_standstill_"); }
  static void TearDownTestSuite() { removeSuiteResources(); }

  static std::string sequence(const std::string& name, double seconds, const std::vector<sim::StillInterval>& stills,
                              const std::vector<double>& crossings) {
    const fs::path dir = root() / name;
    if (!fs::exists(dir / "groundtruth.txt")) {
      sim::SimOptions options = shortRunSimOptions(sim::Scenario::kStatic, 1, seconds);
      options.stills = stills;
      options.occlusion_at_s = crossings;
      sim::writeSequence(options, dir.string(), 0);
    }
    return dir.string();
  }

  static Settings settings(const std::string& dir) { return shortRunSettings(dir); }
};

TEST_F(StandstillEndToEnd, AStillStartInitialisesTheImuFromRest) {
  // ImuInit.RestTime (2 s) after the first window of the zero-velocity test (0.3 s), at rest.
  constexpr double kInitBy_s = 2.7;
  const std::string dir = sequence("still_start", 4.0, {{0.0, 3.0}}, {});
  const Settings s = settings(dir);
  ASSERT_TRUE(s.tracking.zupt && s.imu_init.from_rest);
  io::SequenceReaderOptions reader_options;
  reader_options.calib_override = s.calib;
  io::SequenceReader reader = io::SequenceReader::open(dir, reader_options);
  SystemOptions options;
  options.threaded = false;
  System system(s, vocabulary(), options);
  std::optional<mapping::ImuState> at_rest;
  double first_t_s = -1.0;
  while (std::optional<io::RgbdImuFrame> input = reader.next()) {
    if (first_t_s < 0.0) first_t_s = input->t_s;
    system.trackFrame(*input);
    if (input->t_s <= kInitBy_s && system.imuState().initialised && !at_rest) at_rest = system.imuState();
  }
  system.shutdown();
  ASSERT_TRUE(at_rest.has_value()) << "the IMU did not initialise within the first " << kInitBy_s << " s of rest";
  // The map's world is the first frame's body: the true gravity there is R_w_b(0)^T (0, 0, -9.81).
  const io::Trajectory& truth = reader.groundTruth();
  ASSERT_FALSE(truth.empty());
  ASSERT_NEAR(truth.front().t_s, first_t_s, 1e-6);
  const Mat3 R_w_b0 = truth.front().T_w_x.rotationMatrix() * sim::SimOptions::T_b_c().rotationMatrix().transpose();
  const Vec3 g_true = R_w_b0.transpose() * Vec3(0.0, 0.0, -9.81);
  const double angle_deg = angleDeg(at_rest->g_w, g_true);
  log::info("still start: g_w ", angle_deg, " deg from the truth, b_g error ",
            (at_rest->bias.b_g - trueGyroBias(dir, 1.0)).transpose().format(Eigen::IOFormat(6)), " rad/s");
  EXPECT_LT(angle_deg, 0.5);
  // The gyro bias from RestTime s of rest: sigma = IMU.NoiseGyro / sqrt(RestTime) per axis; the
  // error's norm within sqrt(3) sigma (its rms), each axis within 3 sigma (measured 0.18, 0.55 and
  // 0.44 mrad/s against sigma 0.71 mrad/s, gravity 0.27 deg; the simulator draws the bias with
  // 2 mrad/s per axis).
  const double sigma_b_g = s.calib.imu.noise_gyro / std::sqrt(s.imu_init.rest_time_s);
  const Vec3 error = at_rest->bias.b_g - trueGyroBias(dir, 1.0);
  EXPECT_LT(error.norm(), std::sqrt(3.0) * sigma_b_g);
  for (int axis = 0; axis < 3; ++axis) EXPECT_LT(std::abs(error[axis]), 3.0 * sigma_b_g) << axis;
}

TEST_F(StandstillEndToEnd, AStandstillAmongMoversHoldsThePoseAndMakesNoKeyFrame) {
  constexpr double kStillFrom = 5.0, kStillTo = 8.0;
  const std::string dir = sequence("standstill", 9.0, {{kStillFrom, kStillTo - kStillFrom}}, {kStillFrom + 0.2});
  const Settings s = settings(dir);
  io::SequenceReaderOptions reader_options;
  reader_options.calib_override = s.calib;
  io::SequenceReader reader = io::SequenceReader::open(dir, reader_options);
  SystemOptions options;
  options.threaded = false;
  System system(s, vocabulary(), options);
  int frames = 0;
  while (std::optional<io::RgbdImuFrame> input = reader.next()) {
    system.trackFrame(*input);
    ++frames;
  }
  system.shutdown();
  EXPECT_EQ(system.counts().frames_with_pose, frames);
  const std::vector<FramePose> online = system.onlineTrajectory();
  const FramePose* first = nullptr;
  double drift_m = 0.0;
  for (const FramePose& pose : online) {
    if (pose.t_s < kStillFrom || pose.t_s > kStillTo) continue;
    if (first == nullptr) first = &pose;
    drift_m = std::max(drift_m, (pose.T_w_c.translation() - first->T_w_c.translation()).norm());
  }
  ASSERT_NE(first, nullptr);
  log::info("standstill: online drift while still ", drift_m * 1000.0, " mm");
  EXPECT_LT(drift_m, 0.003);
  for (const KeyFrameRecord& kf : system.keyFrames())
    EXPECT_FALSE(kf.t_s > kStillFrom + 0.6 && kf.t_s <= kStillTo) << "keyframe at " << kf.t_s << " s while still";
}

TEST_F(StandstillEndToEnd, AViewTooPoorForAMapIsCarriedByTheImuUntilTheMapStarts) {
  // A still start of 1.5 s whose colour images are blank until 2.5 s (no keypoint: no map can
  // start), then the robot's normal drive. Tracking.PreMapImuPose gives those frames the IMU's pose
  // (held at rest, gravity and gyro bias taken there, then integrated for 1 s of motion), and the
  // map starts at the dead-reckoned pose, so the run is one trajectory.
  constexpr double kBlankUntil_s = 2.5;
  const std::string dir = sequence("blind_start", 5.0, {{0.0, 1.5}}, {});
  for (const bool on : {true, false}) {
    Settings s = settings(dir);
    s.tracking.pre_map_imu_pose = on;
    io::SequenceReaderOptions reader_options;
    reader_options.calib_override = s.calib;
    io::SequenceReader reader = io::SequenceReader::open(dir, reader_options);
    SystemOptions options;
    options.threaded = false;
    System system(s, vocabulary(), options);
    int frames = 0, blank = 0;
    while (std::optional<io::RgbdImuFrame> input = reader.next()) {
      if (input->t_s < kBlankUntil_s) {
        input->color_bgr.setTo(cv::Scalar(128, 128, 128));
        ++blank;
      }
      system.trackFrame(*input);
      ++frames;
    }
    system.shutdown();
    const SystemCounts counts = system.counts();
    if (!on) {
      EXPECT_EQ(counts.frames_with_pose, frames - blank);
      EXPECT_EQ(counts.frames_before_map, 0);
      continue;
    }
    EXPECT_EQ(counts.frames_with_pose, frames);
    EXPECT_EQ(counts.frames_before_map, blank);
    // The online poses relative to the first frame's against the truth's: held, then dead-reckoned.
    const io::Trajectory& truth = reader.groundTruth();
    const std::vector<FramePose> online = system.onlineTrajectory();
    ASSERT_FALSE(online.empty());
    const SE3 T_c0_w = online.front().T_w_c.inverse();
    const SE3 T_c0_w_true = truthNearest(truth, online.front().t_s).inverse();
    double worst_before_m = 0.0, travelled_m = 0.0;
    for (const FramePose& pose : online) {
      if (pose.t_s >= kBlankUntil_s) break;
      const SE3 T_c0_c_true = T_c0_w_true * truthNearest(truth, pose.t_s);
      travelled_m = T_c0_c_true.translation().norm();
      worst_before_m = std::max(worst_before_m, ((T_c0_w * pose.T_w_c).translation() - T_c0_c_true.translation()).norm());
    }
    const double ate_m =
        eval::computeAte(eval::associateTrajectories(truth, toTumTrajectory(system.trajectory())), false).error_m.rmse;
    log::info("blind start: ", counts.frames_before_map, " frames before the map, worst dead-reckoned position ",
              worst_before_m * 1000.0, " mm off after ", travelled_m, " m; ATE of the run ", ate_m * 1000.0, " mm");
    // Measured: 18.6 mm after 0.198 m (1 s of motion on this IMU's noise: 1 mrad/s/sqrt(Hz) of gyro,
    // a gyro bias from 0.8 s of rest, 0.3 deg off by then), ATE 6.6 mm. Taking the zero-velocity
    // test's late rest as true (no replay) left it 83 mm off, ATE 43 mm; a held position 198 mm.
    EXPECT_GT(travelled_m, 0.15);
    EXPECT_LT(worst_before_m, 0.04);
    EXPECT_LT(ate_m, 0.012);
  }
}

TEST_F(StandstillEndToEnd, AMapStartedAfterARestInitialisesTheImuFromThatRest) {
  // The blind start above: the map starts moving at 2.5 s, so ImuInit.FromRest cannot apply, and the
  // map's own initialisation needs ImuInit.MinTime (2 s) of keyframes. ImuInit.FromPreMapRest takes
  // gravity and the gyro bias from the rest before the map and initialises on the map's first
  // ImuInit.PreMapMinTime (0.5 s) of keyframes.
  constexpr double kBlankUntil_s = 2.5;
  constexpr double kInitBy_s = kBlankUntil_s + 1.0;
  const std::string dir = sequence("blind_start", 5.0, {{0.0, 1.5}}, {});
  for (const bool on : {true, false}) {
    Settings s = settings(dir);
    ASSERT_TRUE(s.tracking.pre_map_imu_pose);
    s.imu_init.from_pre_map_rest = on;
    io::SequenceReaderOptions reader_options;
    reader_options.calib_override = s.calib;
    io::SequenceReader reader = io::SequenceReader::open(dir, reader_options);
    SystemOptions options;
    options.threaded = false;
    System system(s, vocabulary(), options);
    std::optional<mapping::ImuState> first;
    double first_t_s = -1.0, init_t_s = -1.0;
    while (std::optional<io::RgbdImuFrame> input = reader.next()) {
      if (first_t_s < 0.0) first_t_s = input->t_s;
      if (input->t_s < kBlankUntil_s) input->color_bgr.setTo(cv::Scalar(128, 128, 128));
      system.trackFrame(*input);
      if (!first && system.imuState().initialised) {
        first = system.imuState();
        init_t_s = input->t_s;
      }
    }
    const double ate_m =
        eval::computeAte(eval::associateTrajectories(reader.groundTruth(), toTumTrajectory(system.trajectory())), false)
            .error_m.rmse;
    system.shutdown();
    log::info("blind start, ImuInit.FromPreMapRest ", on, ": IMU initialised at ", init_t_s, " s, ATE ",
              ate_m * 1000.0, " mm");
    EXPECT_LT(ate_m, 0.012);
    if (!on) {
      // The map's own initialisation: not before ImuInit.MinTime of keyframes.
      EXPECT_TRUE(!first || init_t_s > kBlankUntil_s + s.imu_init.min_time_s - 0.1) << init_t_s;
      continue;
    }
    ASSERT_TRUE(first.has_value()) << "the IMU did not initialise";
    EXPECT_LE(init_t_s, kInitBy_s);
    const io::Trajectory& truth = reader.groundTruth();
    ASSERT_NEAR(truth.front().t_s, first_t_s, 1e-6);
    const Mat3 R_w_b0 = truth.front().T_w_x.rotationMatrix() * sim::SimOptions::T_b_c().rotationMatrix().transpose();
    const Vec3 g_true = R_w_b0.transpose() * Vec3(0.0, 0.0, -9.81);
    const double angle_deg = angleDeg(first->g_w, g_true);
    const Vec3 error = first->bias.b_g - trueGyroBias(dir, 1.0);
    log::info("blind start: g_w ", angle_deg, " deg from the truth, b_g error ",
              error.transpose().format(Eigen::IOFormat(6)), " rad/s");
    EXPECT_LT(angle_deg, 0.5);
    // The rest the dead reckoning trusts ends 0.6 s before the zero-velocity test calls the motion
    // (0.87 s of the 1.5 s here): the gyro bias's sigma per axis is IMU.NoiseGyro / sqrt(0.8 s) at
    // most. Each axis within 3 sigma, the norm within the 99.7 % bound of a 3-dof chi2 (3.8 sigma).
    // Measured: 2.06, 0.21, 0.34 mrad/s (sigma 1.1; the rest's own reading was 2.0 mrad/s off in x,
    // the map's own initialisation 0.57), gravity 0.17 deg; initialised at 3.2 s (4.87 s without).
    const double sigma_b_g = s.calib.imu.noise_gyro / std::sqrt(0.8);
    EXPECT_LT(error.norm(), 3.8 * sigma_b_g);
    for (int axis = 0; axis < 3; ++axis) EXPECT_LT(std::abs(error[axis]), 3.0 * sigma_b_g) << axis;
  }
}

}  // namespace
}  // namespace ltlo::system
