#include "ltlo/sim/simulator.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "ltlo/core/errors.h"
#include "ltlo/core/settings_file.h"
#include "ltlo/io/imu_io.h"

namespace ltlo::sim {
namespace {

SimOptions smallOptions(Scenario scenario, double seconds, bool noise_free) {
  SimOptions o;
  o.width_px = 160;
  o.height_px = 120;
  o.scenario = scenario;
  o.seed = 5;
  o.duration_s = seconds;
  o.noise_free = noise_free;
  return o;
}

// The room (photographs decoded once per test process; each simulator reschedules its boxes).
const Scene& sharedRoom() {
  static const Scene room = Scene::buildRoom(SimOptions().texture_dir);
  return room;
}

double median(std::vector<double> values) {
  EXPECT_FALSE(values.empty());
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

// One noise-free "carried" sequence shared by the tests below: the box slides in at 0.4 s.
class NoiseFreeSim : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim_ = new Simulator(smallOptions(Scenario::kCarried, 2.0, true), sharedRoom());
  }
  static void TearDownTestSuite() {
    delete sim_;
    sim_ = nullptr;
  }
  static Simulator* sim_;
};
Simulator* NoiseFreeSim::sim_ = nullptr;

TEST(RobotTrajectory, DerivativesMatchFiniteDifferences) {
  const RobotTrajectory trajectory(TrajectoryParams{}, 3);
  const double h = 1e-5;
  for (double t = 0.3; t < 40.0; t += 1.3) {
    const RobotState s = trajectory.state(t);
    const RobotState sp = trajectory.state(t + h), sm = trajectory.state(t - h);
    const Vec3 v_num = (sp.T_w_b.translation() - sm.T_w_b.translation()) / (2 * h);
    const Vec3 a_num = (sp.v_w_b - sm.v_w_b) / (2 * h);
    const Vec3 w_num =
        so3Log(sm.T_w_b.rotationMatrix().transpose() * sp.T_w_b.rotationMatrix()) / (2 * h);
    EXPECT_LT((v_num - s.v_w_b).norm(), 1e-7) << t;
    EXPECT_LT((a_num - s.a_w_b).norm(), 1e-6) << t;
    EXPECT_LT((w_num - s.omega_b).norm(), 1e-6) << t;
    const double speed = s.v_w_b.head<2>().norm();
    EXPECT_GT(speed, 0.3);
    EXPECT_LT(speed, 0.6);
  }
}

TEST(RobotTrajectory, PathIsClosedAndRevisited) {
  const RobotTrajectory trajectory(TrajectoryParams{}, 3);
  // Within two laps (< 70 s) the robot comes back within 10 cm of its start after leaving it.
  const Vec3 start = trajectory.state(0.0).T_w_b.translation();
  double closest_return_m = 1e9;
  for (double t = 15.0; t < 70.0; t += 0.05)
    closest_return_m =
        std::min(closest_return_m, (trajectory.state(t).T_w_b.translation() - start).norm());
  EXPECT_LT(closest_return_m, 0.1);
}

// Stops (issue 32): the pose is held exactly, the slow-down and speed-up are smooth (velocity,
// acceleration and rate are still the derivatives of the pose), and after the stop the robot goes on
// along the same path, D + ramp seconds behind.
TEST(RobotTrajectory, StillIntervalsHoldThePoseAndTheRampsAreSmooth) {
  TrajectoryParams params;
  params.stills = {{6.0, 4.0}};
  const RobotTrajectory still(params, 3), moving(TrajectoryParams{}, 3);
  const RobotState held = still.state(6.0);
  for (double t = 6.0; t <= 10.0; t += 0.05) {
    const RobotState s = still.state(t);
    EXPECT_EQ((s.T_w_b.translation() - held.T_w_b.translation()).norm(), 0.0) << t;
    EXPECT_EQ(so3Log(s.T_w_b.rotationMatrix().transpose() * held.T_w_b.rotationMatrix()).norm(), 0.0) << t;
    EXPECT_EQ(s.v_w_b.norm() + s.a_w_b.norm() + s.omega_b.norm(), 0.0) << t;
  }
  const double h = 1e-5;
  for (double t = 4.93; t < 12.0; t += 0.17) {  // through both ramps
    const RobotState s = still.state(t);
    const RobotState sp = still.state(t + h), sm = still.state(t - h);
    const Vec3 v_num = (sp.T_w_b.translation() - sm.T_w_b.translation()) / (2 * h);
    const Vec3 a_num = (sp.v_w_b - sm.v_w_b) / (2 * h);
    const Vec3 w_num = so3Log(sm.T_w_b.rotationMatrix().transpose() * sp.T_w_b.rotationMatrix()) / (2 * h);
    EXPECT_LT((v_num - s.v_w_b).norm(), 1e-7) << t;
    EXPECT_LT((a_num - s.a_w_b).norm(), 1e-5) << t;
    EXPECT_LT((w_num - s.omega_b).norm(), 1e-6) << t;
  }
  // Before the slow-down: the moving path; after the speed-up: the moving path D + r = 5 s later.
  EXPECT_EQ((still.state(4.5).T_w_b.translation() - moving.state(4.5).T_w_b.translation()).norm(), 0.0);
  EXPECT_LT((still.state(14.0).T_w_b.translation() - moving.state(9.0).T_w_b.translation()).norm(), 1e-12);
  EXPECT_LT((still.state(14.0).v_w_b - moving.state(9.0).v_w_b).norm(), 1e-12);
  // A still start: at rest from t = 0, then on along the path 3.5 s behind.
  params.stills = {{0.0, 3.0}};
  const RobotTrajectory start(params, 3);
  EXPECT_EQ((start.state(0.0).T_w_b.translation() - moving.state(0.0).T_w_b.translation()).norm(), 0.0);
  EXPECT_EQ((start.state(2.9).T_w_b.translation() - moving.state(0.0).T_w_b.translation()).norm(), 0.0);
  EXPECT_EQ(start.state(1.0).v_w_b.norm(), 0.0);
  EXPECT_LT((start.state(8.0).T_w_b.translation() - moving.state(4.5).T_w_b.translation()).norm(), 1e-12);
  params.stills = {{6.0, 4.0}, {10.5, 2.0}};  // within the first stop's speed-up
  EXPECT_THROW(RobotTrajectory(params, 3), InputError);
  params.stills = {{0.5, 2.0}};  // no room to slow down
  EXPECT_THROW(RobotTrajectory(params, 3), InputError);
}

// While still, the written ground truth is one pose and the IMU measures gravity in the body frame
// plus bias and white noise: the mean over the stretch agrees within 4 sigma / sqrt(N).
TEST(Simulator, StillRobotHoldsItsPoseAndTheImuSeesOnlyGravity) {
  SimOptions o = smallOptions(Scenario::kStatic, 8.0, false);
  o.stills = {{2.0, 4.0}};
  Simulator sim(o, sharedRoom());
  const io::Trajectory gt = sim.groundTruth();
  const io::StampedPose* first = nullptr;
  for (const io::StampedPose& pose : gt) {
    if (pose.t_s < 2.0 || pose.t_s > 6.0) continue;
    if (first == nullptr) first = &pose;
    EXPECT_EQ((pose.T_w_x.translation() - first->T_w_x.translation()).norm(), 0.0) << pose.t_s;
    EXPECT_EQ(so3Log(pose.T_w_x.rotationMatrix().transpose() * first->T_w_x.rotationMatrix()).norm(), 0.0);
  }
  ASSERT_NE(first, nullptr);
  EXPECT_GT((gt.back().T_w_x.translation() - first->T_w_x.translation()).norm(), 0.3);  // moves on
  const Mat3 R_w_b = sim.trajectory().state(4.0).T_w_b.rotationMatrix();
  const Vec3 g_b = R_w_b.transpose() * Vec3(0, 0, kGravityMps2);  // specific force at rest
  Vec3 acc_sum = Vec3::Zero(), gyro_sum = Vec3::Zero();
  int n = 0;
  for (const ImuSample& sample : sim.imu()) {
    if (sample.t_s < 2.0 || sample.t_s > 6.0) continue;
    acc_sum += sample.acc_mps2 - sample.bias_acc;
    gyro_sum += sample.gyro_rad_s - sample.bias_gyro;
    ++n;
  }
  ASSERT_GT(n, 700);
  const double acc_sigma = o.noise_acc * std::sqrt(o.imu_rate_hz) / std::sqrt(n);
  const double gyro_sigma = o.noise_gyro * std::sqrt(o.imu_rate_hz) / std::sqrt(n);
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_NEAR(acc_sum[axis] / n, g_b[axis], 4.0 * acc_sigma) << axis;
    EXPECT_NEAR(gyro_sum[axis] / n, 0.0, 4.0 * gyro_sigma) << axis;
  }
  EXPECT_GT(std::abs(g_b.x()) + std::abs(g_b.y()), 1e-3);  // a tilted body: not just the z axis
}

// --occlusion-at: a box crosses the view of the still camera (in from one side, out to the other)
// with an exact mask, and the regular events overlapping it are dropped.
TEST(Simulator, CrossingBoxPassesInFrontOfTheStillCamera) {
  SimOptions o = smallOptions(Scenario::kLtlo, 12.0, true);
  o.stills = {{2.0, 9.0}};
  o.occlusion_at_s = {3.0};
  Simulator sim(o, sharedRoom());
  const DynamicBox* crossing = nullptr;
  for (const DynamicBox& b : sim.scene().boxes) {
    if (b.crosses) crossing = &b;
    else EXPECT_TRUE(b.t_out_s <= 3.0 || b.t_in_s >= 3.0 + 2.0 + 4.0) << b.t_in_s << " " << b.t_out_s;
  }
  ASSERT_NE(crossing, nullptr);
  EXPECT_EQ(crossing->t_in_s, 3.0);
  ASSERT_LE(crossing->t_out_s, 11.0);
  const SE3 T_c_w = sim.T_w_c(3.0).inverse();
  auto lateralInCamera = [&](double t_s) {  // x of the box centre in the camera frame
    for (const auto& [index, T_w_o] : sim.scene().dynamicPoses(t_s, sim.trajectory()))
      if (&sim.scene().boxes[index] == crossing) return (T_c_w * T_w_o).translation().x();
    ADD_FAILURE() << "crossing box absent at " << t_s;
    return 0.0;
  };
  const double x_in = lateralInCamera(3.05), x_out = lateralInCamera(crossing->t_out_s - 0.05);
  EXPECT_GT(std::abs(x_in), 1.5);
  EXPECT_GT(std::abs(x_out), 1.5);
  EXPECT_LT(x_in * x_out, 0.0);  // entered on one side, left on the other
  const int held = static_cast<int>(std::lround((crossing->t_in_s + 1.5) * o.fps));
  const SimFrame frame = sim.renderFrame(held);
  EXPECT_GT(frame.dynamic_fraction, 0.3);
  const render::RenderResult dynamic = sim.renderDynamicOnly(held);
  EXPECT_LE(cv::countNonZero(frame.mask), cv::countNonZero(dynamic.labels));
  EXPECT_GT(cv::countNonZero(frame.mask), static_cast<int>(0.3 * frame.mask.total()));
}

// Trapezoidal integration of the noise-free IMU from the ground-truth state at t = 0.
TEST_F(NoiseFreeSim, ImuIntegrationReproducesGroundTruth) {
  const std::vector<ImuSample>& imu = sim_->imu();
  const RobotTrajectory& trajectory = sim_->trajectory();
  const Vec3 g_w(0, 0, -kGravityMps2);
  const RobotState s0 = trajectory.state(0.0);
  Mat3 R = s0.T_w_b.rotationMatrix();
  Vec3 p = s0.T_w_b.translation(), v = s0.v_w_b;
  const double dt = 1.0 / sim_->options().imu_rate_hz;
  const int steps = static_cast<int>(std::round(1.0 / dt));
  ASSERT_GT(static_cast<int>(imu.size()), steps);
  for (int k = 0; k < steps; ++k) {
    EXPECT_NEAR(imu[k + 1].t_s - imu[k].t_s, dt, 1e-12);
    const Vec3 a_k = R * imu[k].acc_mps2 + g_w;
    const Mat3 R_next = R * so3Exp(0.5 * (imu[k].gyro_rad_s + imu[k + 1].gyro_rad_s) * dt);
    const Vec3 a_next = R_next * imu[k + 1].acc_mps2 + g_w;
    p += v * dt + (a_k / 3.0 + a_next / 6.0) * dt * dt;
    v += 0.5 * (a_k + a_next) * dt;
    R = R_next;
  }
  const SE3 T_w_b_integrated(R, p);
  const SE3 T_w_c_integrated = T_w_b_integrated * SimOptions::T_b_c();
  const io::Trajectory gt = sim_->groundTruth();
  const io::StampedPose& at_1s = gt[30];
  ASSERT_NEAR(at_1s.t_s, 1.0, 1e-9);
  EXPECT_LT((T_w_c_integrated.translation() - at_1s.T_w_x.translation()).norm(), 1e-3);
  EXPECT_LT(
      so3Log(T_w_c_integrated.rotationMatrix().transpose() * at_1s.T_w_x.rotationMatrix()).norm(),
      1e-4);
  EXPECT_LT((v - trajectory.state(1.0).v_w_b).norm(), 1e-3);
}

TEST(ImuSimulator, NoiseMatchesConfiguredDensities) {
  SimOptions o = smallOptions(Scenario::kStatic, 60.0, false);
  o.gyro_walk = 0.0;  // constant biases: the residual is white noise only
  o.acc_walk = 0.0;
  const RobotTrajectory trajectory(TrajectoryParams{}, o.seed);
  const std::vector<ImuSample> noisy = simulateImu(trajectory, o);
  o.noise_free = true;
  const std::vector<ImuSample> clean = simulateImu(trajectory, o);
  double gyro_sq = 0.0, acc_sq = 0.0;
  for (size_t k = 0; k < noisy.size(); ++k) {
    gyro_sq += (noisy[k].gyro_rad_s - clean[k].gyro_rad_s - noisy[k].bias_gyro).squaredNorm();
    acc_sq += (noisy[k].acc_mps2 - clean[k].acc_mps2 - noisy[k].bias_acc).squaredNorm();
  }
  const double n = 3.0 * noisy.size();
  EXPECT_NEAR(std::sqrt(gyro_sq / n), o.noise_gyro * std::sqrt(o.imu_rate_hz),
              0.03 * o.noise_gyro * std::sqrt(o.imu_rate_hz));
  EXPECT_NEAR(std::sqrt(acc_sq / n), o.noise_acc * std::sqrt(o.imu_rate_hz),
              0.03 * o.noise_acc * std::sqrt(o.imu_rate_hz));
  // At rest-like orientation the accelerometer reads about +g along body z.
  EXPECT_NEAR(clean[0].acc_mps2.z(), kGravityMps2, 0.5);
}

// Static pixels of frame t, back-projected with depth and moved with the ground-truth poses into
// frame t+1, land on the same depth (inverse depth interpolated bilinearly) and intensity.
TEST_F(NoiseFreeSim, BackProjectionIntoNextFrameMatchesDepthAndIntensity) {
  const PinholeCamera& cam = sim_->camera();
  std::vector<double> depth_err_m, intensity_err;
  for (int i : {2, 20, 40}) {
    const SimFrame a = sim_->renderFrame(i), b = sim_->renderFrame(i + 1);
    cv::Mat gray_a, gray_b;
    cv::cvtColor(a.bgr, gray_a, cv::COLOR_BGR2GRAY);
    cv::cvtColor(b.bgr, gray_b, cv::COLOR_BGR2GRAY);
    const SE3 T_b_a = b.T_w_c.inverse() * a.T_w_c;
    for (int v = 2; v < cam.height() - 2; v += 2) {
      for (int u = 2; u < cam.width() - 2; u += 2) {
        const float z = a.depth_m.at<float>(v, u);
        if (z <= 0 || a.mask.at<uint8_t>(v, u)) continue;
        const Vec3 p_b = T_b_a * cam.backProject(Vec2(u, v), z);
        const Vec2 uv = cam.project(p_b);
        if (!cam.isInImage(uv, 1.0)) continue;
        const int u0 = static_cast<int>(uv.x()), v0 = static_cast<int>(uv.y());
        const double fu = uv.x() - u0, fv = uv.y() - v0;
        double inv_depth = 0.0, intensity = 0.0, lo = 1e9, hi = 0.0;
        bool usable = true;
        for (int dv = 0; dv < 2; ++dv)
          for (int du = 0; du < 2; ++du) {
            const float zb = b.depth_m.at<float>(v0 + dv, u0 + du);
            usable = usable && zb > 0 && !b.mask.at<uint8_t>(v0 + dv, u0 + du);
            lo = std::min<double>(lo, zb);
            hi = std::max<double>(hi, zb);
            const double w = (du ? fu : 1 - fu) * (dv ? fv : 1 - fv);
            inv_depth += w / std::max(zb, 1e-3f);
            intensity += w * gray_b.at<uint8_t>(v0 + dv, u0 + du);
          }
        if (!usable || hi - lo > 0.05 * lo) continue;  // skip depth edges
        depth_err_m.push_back(std::abs(1.0 / inv_depth - p_b.z()));
        intensity_err.push_back(std::abs(intensity - gray_a.at<uint8_t>(v, u)));
      }
    }
  }
  ASSERT_GT(depth_err_m.size(), 3000u);
  RecordProperty("median_depth_err_mm", std::to_string(1e3 * median(depth_err_m)));
  RecordProperty("median_intensity_err", std::to_string(median(intensity_err)));
  EXPECT_LT(median(depth_err_m), 0.005);
  EXPECT_LT(median(intensity_err), 8.0);
}

TEST_F(NoiseFreeSim, MaskCoversExactlyTheVisibleDynamicObjects) {
  int frames_with_objects = 0;
  for (int i : {5, 15, 25, 30, 35, 40, 55}) {
    const SimFrame frame = sim_->renderFrame(i);
    const render::RenderResult dynamic = sim_->renderDynamicOnly(i);
    const render::RenderResult room = sim_->renderStaticOnly(i);
    int wrong = 0, dynamic_pixels = 0;
    for (int v = 0; v < frame.mask.rows; ++v)
      for (int u = 0; u < frame.mask.cols; ++u) {
        const float zd = dynamic.depth_m.at<float>(v, u), zs = room.depth_m.at<float>(v, u);
        const bool expected = zd > 0 && (zs == 0 || zd < zs);
        dynamic_pixels += expected;
        wrong += expected != (frame.mask.at<uint8_t>(v, u) == 255);
      }
    EXPECT_EQ(wrong, 0) << "frame " << i;
    frames_with_objects += dynamic_pixels > static_cast<int>(frame.mask.total() / 5);
  }
  EXPECT_GE(frames_with_objects, 4);  // the check is not vacuous
}

TEST(Simulator, DepthNoiseGrowsWithDistanceSquared) {
  SimOptions o = smallOptions(Scenario::kStatic, 0.5, false);
  o.depth_edge_dropout = 0.0;
  o.depth_random_dropout = 0.0;
  Simulator sim(o, sharedRoom());
  EXPECT_TRUE(sim.scene().photo_textures);  // the wallpaper packages are installed on CI
  const SimFrame noisy = sim.renderFrame(3);
  const render::RenderResult clean = sim.renderStaticOnly(3);
  // Normalised residual (z_noisy - z) / z^2 has std = noise at 1 m (plus 1 mm quantisation).
  double sum_sq = 0.0;
  int count = 0;
  for (int v = 0; v < noisy.depth_m.rows; ++v)
    for (int u = 0; u < noisy.depth_m.cols; ++u) {
      const double z = clean.depth_m.at<float>(v, u), zn = noisy.depth_m.at<float>(v, u);
      if (zn <= 0 || z < 1.5) continue;
      sum_sq += std::pow((zn - z) / (z * z), 2);
      ++count;
    }
  ASSERT_GT(count, 1000);
  EXPECT_NEAR(std::sqrt(sum_sq / count), o.depth_noise_at_1m_m, 0.15 * o.depth_noise_at_1m_m);
}

TEST(Simulator, OutagesBlankTheCameraButNotTheGroundTruth) {
  SimOptions o = smallOptions(Scenario::kStatic, 1.0, false);
  o.outages.push_back({SensorOutage::Kind::kBlack, 0.1, 0.1});
  o.outages.push_back({SensorOutage::Kind::kNoDepth, 0.5, 0.1});
  Simulator sim(o, sharedRoom());
  const int black = static_cast<int>(std::lround(0.15 * o.fps));
  const int no_depth = static_cast<int>(std::lround(0.55 * o.fps));
  const int normal = static_cast<int>(std::lround(0.35 * o.fps));
  const SimFrame b = sim.renderFrame(black), d = sim.renderFrame(no_depth), n = sim.renderFrame(normal);
  EXPECT_EQ(cv::countNonZero(b.bgr.reshape(1)), 0);
  EXPECT_EQ(cv::countNonZero(b.depth_raw), 0);
  EXPECT_GT(cv::countNonZero(d.bgr.reshape(1)), static_cast<int>(d.bgr.total()));  // colour kept
  EXPECT_EQ(cv::countNonZero(d.depth_m), 0);
  EXPECT_GT(cv::countNonZero(n.depth_m), static_cast<int>(n.depth_m.total() / 2));
  EXPECT_LT((b.T_w_c.translation() - sim.T_w_c(b.t_s).translation()).norm(), 1e-12);
}

// Over two minutes the ltlo scenario keeps more than 40 % of the image dynamic in 55-75 % of the
// frames, with stretches of over 8 s (several metres of travel).
TEST(Simulator, LtloScenarioOccludesMostFramesForLongStretches) {
  SimOptions o = smallOptions(Scenario::kLtlo, 120.0, true);
  o.width_px = 80;
  o.height_px = 60;
  o.fps = 5.0;
  o.seed = 2;
  Simulator sim(o, sharedRoom());
  int occluded = 0, run = 0, longest = 0;
  for (int i = 0; i < sim.numFrames(); ++i) {
    const render::RenderResult dynamic = sim.renderDynamicOnly(i);
    const double fraction = sim.renderFrame(i).dynamic_fraction;
    ASSERT_LE(
        fraction,
        cv::countNonZero(dynamic.labels) / static_cast<double>(dynamic.labels.total()) + 1e-12);
    if (fraction > 0.4) {
      ++occluded;
      longest = std::max(longest, ++run);
    } else {
      run = 0;
    }
  }
  const double share = occluded / static_cast<double>(sim.numFrames());
  EXPECT_GT(share, 0.55);
  EXPECT_LT(share, 0.75);
  EXPECT_GT(longest / o.fps, 8.0);
}

// The room is rich in corners everywhere: ORB finds its full budget of keypoints spread over the
// image in static views around the loop.
TEST(Simulator, StaticViewsAreRichInOrbFeatures) {
  SimOptions o = smallOptions(Scenario::kStatic, 30.0, false);
  o.width_px = 640;
  o.height_px = 480;
  Simulator sim(o, sharedRoom());
  const cv::Ptr<cv::ORB> orb = cv::ORB::create(1000);
  for (int i : {0, 200, 400, 600, 800}) {
    cv::Mat gray;
    cv::cvtColor(sim.renderFrame(i).bgr, gray, cv::COLOR_BGR2GRAY);
    std::vector<cv::KeyPoint> keypoints;
    orb->detect(gray, keypoints);
    int occupied[4][4] = {};
    for (const cv::KeyPoint& kp : keypoints)
      occupied[static_cast<int>(kp.pt.y * 4 / 480)][static_cast<int>(kp.pt.x * 4 / 640)] = 1;
    int cells = 0;
    for (const auto& row : occupied)
      for (int c : row) cells += c;
    EXPECT_GE(keypoints.size(), 900u) << "frame " << i;
    EXPECT_GE(cells, 12) << "frame " << i;
    RecordProperty("orb_keypoints_frame_" + std::to_string(i), static_cast<int>(keypoints.size()));
    RecordProperty("orb_cells_frame_" + std::to_string(i), cells);
  }
}

std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

TEST(Simulator, WritesTheDataFormatLayoutDeterministically) {
  namespace fs = std::filesystem;
  const fs::path root = fs::temp_directory_path() / ("ltlo_sim_test_" + std::to_string(::getpid()));
  const SimOptions o = smallOptions(Scenario::kCarried, 0.5, false);
  Simulator sim_a(o, sharedRoom()), sim_b(o, sharedRoom());
  const SequenceStats stats = writeSequence(sim_a, (root / "a").string(), 0);
  writeSequence(sim_b, (root / "b").string(), 0);
  EXPECT_GT(stats.mean_fraction_when_present, 0.1);
  EXPECT_EQ(stats.num_frames, 15);

  std::vector<std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(root / "a"))
    if (entry.is_regular_file()) files.push_back(fs::relative(entry.path(), root / "a").string());
  EXPECT_EQ(files.size(), 3u * 15 + 9);  // rgb, depth, masks + 9 text/yaml/ply files
  for (const std::string& f : files)
    EXPECT_EQ(readFile((root / "a" / f).string()), readFile((root / "b" / f).string())) << f;

  const SensorCalib calib = SensorCalib::load((root / "a" / "calib.yaml").string());
  EXPECT_TRUE(calib.has_imu);
  EXPECT_EQ(calib.camera.camera.width(), 160);
  EXPECT_LT((calib.imu.T_b_c.matrix() - SimOptions::T_b_c().matrix()).norm(), 1e-9);
  const io::Trajectory gt = io::readTumTrajectory((root / "a" / "groundtruth.txt").string());
  ASSERT_EQ(gt.size(), 15u);
  const cv::Mat depth =
      cv::imread((root / "a" / "depth" / "0.033333.png").string(), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(depth.type(), CV_16U);
  std::ifstream assoc((root / "a" / "associations.txt").string());
  std::string line;
  std::getline(assoc, line);  // comment
  std::getline(assoc, line);
  EXPECT_EQ(line, "0.000000 rgb/0.000000.png 0.000000 depth/0.000000.png");
  fs::remove_all(root);
}

TEST(Simulator, ImuGapLeavesTheSamplesOutOfImuTxtOnly) {
  namespace fs = std::filesystem;
  const fs::path root = fs::temp_directory_path() / ("ltlo_sim_gap_" + std::to_string(::getpid()));
  SimOptions o = smallOptions(Scenario::kStatic, 0.4, true);
  o.outages.push_back({SensorOutage::Kind::kImuGap, 0.1, 0.15});
  Simulator sim(o, sharedRoom());
  writeSequence(sim, root.string(), 0);
  SequenceOptions warn_only;
  warn_only.max_imu_gap_s = 1.0;
  const ImuSamples imu = io::readImuText((root / "imu.txt").string(), warn_only);
  ASSERT_FALSE(imu.empty());
  double largest_gap_s = 0.0;
  for (size_t i = 0; i < imu.size(); ++i) {
    EXPECT_FALSE(imu[i].t_s >= 0.1 && imu[i].t_s < 0.25) << "sample at " << imu[i].t_s;
    if (i > 0) largest_gap_s = std::max(largest_gap_s, imu[i].t_s - imu[i - 1].t_s);
  }
  // 200 Hz: 30 samples dropped (one more or less where a sample time sits on an edge of the
  // stretch up to rounding), so the gap spans about 31 sample periods.
  EXPECT_NEAR(largest_gap_s, 0.155, 0.0051);
  EXPECT_NEAR(static_cast<double>(sim.imu().size() - imu.size()), 30.0, 1.0);
  // The camera is unaffected: the frame inside the gap has colour and depth.
  const SimFrame frame = sim.renderFrame(static_cast<int>(std::lround(0.2 * o.fps)));
  EXPECT_GT(cv::countNonZero(frame.depth_m), static_cast<int>(frame.depth_m.total() / 2));
  fs::remove_all(root);
}

TEST(Scene, FallsBackToProceduralTexturesWithoutPhotographs) {
  const Scene room = Scene::buildRoom("/nonexistent-texture-dir");
  EXPECT_FALSE(room.photo_textures);
  ASSERT_FALSE(room.textures.empty());
  cv::Mat gray;
  cv::cvtColor(room.textures[0], gray, cv::COLOR_BGR2GRAY);
  cv::Mat edges;
  cv::Canny(gray, edges, 50, 150);
  EXPECT_GT(cv::countNonZero(edges), static_cast<int>(gray.total() / 50));  // textured, not flat
}

TEST(SimOptions, LoadsTheShippedConfigAndRejectsOutOfRange) {
  const std::string dir = std::getenv("LTLO_SOURCE_DIR") ? std::getenv("LTLO_SOURCE_DIR") : ".";
  const SimOptions o = SimOptions::load(SettingsFile(dir + "/config_yaml/simulator.yaml"));
  EXPECT_EQ(o.width_px, 640);
  EXPECT_DOUBLE_EQ(o.imu_rate_hz, 200.0);
  const std::string bad = (std::filesystem::temp_directory_path() / "ltlo_sim_bad.yaml").string();
  std::ofstream(bad) << "%YAML:1.0\nDepth.NoiseAt1m: 0.5\n";
  try {
    SimOptions::load(SettingsFile(bad));
    ADD_FAILURE() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("Depth.NoiseAt1m"), std::string::npos) << e.what();
  }
}

TEST(SimOptions, ReadsTheImuUnderItsOwnKeysAndTheOldOnesWithAWarning) {
  const auto dir = std::filesystem::temp_directory_path();
  const std::string own = (dir / "ltlo_sim_imu_own.yaml").string();
  std::ofstream(own) << "%YAML:1.0\nSim.Imu.NoiseGyro: 2.5e-3\nSim.Imu.AccWalk: 4.0e-4\nSim.Imu.Frequency: 400.0\n";
  const SimOptions o = SimOptions::load(SettingsFile(own));
  EXPECT_DOUBLE_EQ(o.noise_gyro, 2.5e-3);
  EXPECT_DOUBLE_EQ(o.acc_walk, 4.0e-4);
  EXPECT_DOUBLE_EQ(o.imu_rate_hz, 400.0);
  EXPECT_DOUBLE_EQ(o.noise_acc, SimOptions().noise_acc);  // absent: the simulator's default
  EXPECT_DOUBLE_EQ(o.sensorCalib().imu.noise_gyro, 2.5e-3);  // calib.yaml tells the truth

  const std::string old = (dir / "ltlo_sim_imu_old.yaml").string();
  std::ofstream(old) << "%YAML:1.0\nIMU.NoiseAcc: 3.0e-2\n";
  EXPECT_DOUBLE_EQ(SimOptions::load(SettingsFile(old)).noise_acc, 3.0e-2);

  const std::string both = (dir / "ltlo_sim_imu_both.yaml").string();
  std::ofstream(both) << "%YAML:1.0\nIMU.NoiseAcc: 3.0e-2\nSim.Imu.NoiseAcc: 3.0e-2\n";
  try {
    SimOptions::load(SettingsFile(both));
    ADD_FAILURE() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("IMU.NoiseAcc"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("Sim.Imu.NoiseAcc"), std::string::npos) << e.what();
  }
}

TEST(SequenceSpace, EstimateCoversAMeasuredSequenceAndScalesWithPixelsAndFrames) {
  SimOptions vga;
  vga.duration_s = 45.0;
  const std::uintmax_t bytes = expectedSequenceBytes(vga);
  // A 45 s VGA photo-textured sequence measured 1.1-1.2 GB on disk; the estimate has a margin over it.
  EXPECT_GE(bytes, 1'200'000'000u);
  EXPECT_LE(bytes, 2'000'000'000u);
  SimOptions small = vga;
  small.width_px = 320;
  small.height_px = 240;
  small.duration_s = 22.5;
  EXPECT_NEAR(static_cast<double>(expectedSequenceBytes(small)), bytes / 8.0, bytes * 1e-3);
}

TEST(SequenceSpace, TooLittleSpaceIsAnInputErrorNamingTheFolderAndBothSizes) {
  const std::string out = (std::filesystem::temp_directory_path() / "ltlo_space_test" / "not" / "made").string();
  EXPECT_NO_THROW(requireFreeSpace(out, 0));
  try {
    requireFreeSpace(out, std::numeric_limits<std::uintmax_t>::max() / 2);
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(out), std::string::npos) << what;
    EXPECT_NE(what.find("needs about"), std::string::npos) << what;
    EXPECT_NE(what.find("available"), std::string::npos) << what;
  }
  EXPECT_FALSE(std::filesystem::exists(out));  // nothing made for a sequence that cannot fit
}

}  // namespace
}  // namespace ltlo::sim
