// The optim builders recovering known solutions: pose-only tracking with outliers, a small
// visual-inertial window, and IMU initialisation from known poses.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>

#include "common/analytic_trajectory.h"
#include "ltlo/core/lie.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/optim/bundle_adjust.h"
#include "ltlo/optim/pose_graph.h"
#include "ltlo/optim/pose_only_problem.h"

namespace ltlo::optim {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

ProjectionModel testModel() {
  ProjectionModel model;
  model.camera = PinholeCamera(520.0, 520.0, 319.5, 239.5, 640, 480);
  // Camera looking along the body x axis (z_c = x_b), slightly offset.
  Mat3 R_b_c;
  R_b_c << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const SE3 T_b_c(R_b_c, Vec3(0.05, -0.02, 0.01));
  model.T_c_x = T_b_c.inverse();
  model.bf_px_m = 520.0 * 0.08;
  return model;
}

double rotationErrorDeg(const SE3& a, const SE3& b) {
  return so3Log(a.quaternion().conjugate() * b.quaternion()).norm() * kRadToDeg;
}
double translationError(const SE3& a, const SE3& b) { return (a.translation() - b.translation()).norm(); }

// A world point visible from body pose T_w_b at 1.5..5 m.
Vec3 visiblePoint(std::mt19937& rng, const ProjectionModel& model, const SE3& T_w_b) {
  std::uniform_real_distribution<double> u(20.0, 620.0);
  std::uniform_real_distribution<double> v(20.0, 460.0);
  std::uniform_real_distribution<double> depth(1.5, 5.0);
  const Vec3 p_c = model.camera.backProject(Vec2(u(rng), v(rng)), depth(rng));
  return T_w_b * (model.T_c_x.inverse() * p_c);
}

TEST(PoseOnlyProblem, RecoversPoseAndFlagsOutliers) {
  std::mt19937 rng(11);
  std::normal_distribution<double> pixel_noise(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const ProjectionModel model = testModel();
  const SE3 T_w_b_true(so3ExpQuat(Vec3(0.1, -0.3, 0.8)), Vec3(1.0, -2.0, 0.5));

  PoseOnlyProblem problem;
  problem.model = model;
  problem.T_w_b_init = T_w_b_true * SE3(so3ExpQuat(Vec3(0.03, -0.02, 0.04)), Vec3(0.05, -0.04, 0.03));
  std::vector<bool> is_outlier;
  for (int k = 0; k < 250; ++k) {
    const Vec3 p_w = visiblePoint(rng, model, T_w_b_true);
    const Vec3 p_c = model.T_c_x * (T_w_b_true.inverse() * p_w);
    PoseObservation obs;
    obs.p_w = p_w;
    obs.sigma_px = 1.0;
    const bool outlier = k % 5 == 0;  // 20%
    if (outlier) {
      obs.uv = Vec2(640.0 * uniform(rng), 480.0 * uniform(rng));
      obs.depth_m = 1.0 + 4.0 * uniform(rng);
    } else {
      obs.uv = model.camera.project(p_c) + Vec2(pixel_noise(rng), pixel_noise(rng));
      // Depth whose u_r = u - bf / d carries its own independent 1 px noise.
      const double u_r = model.projectRgbd(p_c).z() + pixel_noise(rng);
      obs.depth_m = model.bf_px_m / (obs.uv.x() - u_r);
    }
    if (k % 7 == 3) obs.depth_m = 0.0;  // some features without depth: 2-D edges
    problem.observations.push_back(obs);
    is_outlier.push_back(outlier);
  }

  const PoseOnlyResult result = optimizePose(problem);
  EXPECT_LT(translationError(result.T_w_b, T_w_b_true), 0.01);
  EXPECT_LT(rotationErrorDeg(result.T_w_b, T_w_b_true), 0.1);
  int outliers_flagged = 0, outliers = 0, inliers_kept = 0, inliers = 0;
  for (size_t k = 0; k < is_outlier.size(); ++k) {
    if (is_outlier[k]) {
      ++outliers;
      if (!result.inliers[k]) ++outliers_flagged;
    } else {
      ++inliers;
      if (result.inliers[k]) ++inliers_kept;
    }
  }
  // A random pixel lands within the 95% gate of the truth with probability ~1e-4 per outlier.
  EXPECT_EQ(outliers_flagged, outliers);
  // 95% gate on Gaussian inliers: ~5% rejected; allow up to 10%.
  EXPECT_GE(inliers_kept, static_cast<int>(0.9 * inliers));
  EXPECT_EQ(result.num_inliers, inliers_kept + (outliers - outliers_flagged));
}

TEST(PoseOnlyProblem, InertialLinkRecoversPoseVelocityAndKeepsBias) {
  std::mt19937 rng(12);
  std::normal_distribution<double> pixel_noise(0.0, 1.0);
  const ProjectionModel model = testModel();
  const imu::test::AnalyticTrajectory trajectory;
  const double t_prev = 2.0, t_cur = 2.05;
  const imu::NavState prev = trajectory.state(t_prev);
  const imu::NavState cur = trajectory.state(t_cur);
  auto pim = std::make_shared<imu::Preintegrated>(imu::ImuBias{}, imu::ImuNoise());
  pim->integrate(trajectory.samples(t_prev, t_cur, 200.0));
  const SE3 T_w_b_true(cur.R_w_b, cur.p_w_b);

  PoseOnlyProblem problem;
  problem.model = model;
  problem.T_w_b_init = T_w_b_true * SE3(so3ExpQuat(Vec3(0.01, -0.02, 0.01)), Vec3(0.03, 0.02, -0.02));
  problem.v_w_b_init = cur.v_w_b + Vec3(0.1, -0.1, 0.05);
  for (int k = 0; k < 60; ++k) {
    const Vec3 p_w = visiblePoint(rng, model, T_w_b_true);
    const Vec3 p_c = model.T_c_x * (T_w_b_true.inverse() * p_w);
    PoseObservation obs;
    obs.p_w = p_w;
    obs.uv = model.camera.project(p_c) + Vec2(pixel_noise(rng), pixel_noise(rng));
    obs.depth_m = p_c.z();
    problem.observations.push_back(obs);
  }
  InertialLink link;
  link.T_w_b_prev = SE3(prev.R_w_b, prev.p_w_b);
  link.v_w_b_prev = prev.v_w_b;
  link.pim = pim;
  problem.inertial = link;

  const PoseOnlyResult result = optimizePose(problem);
  EXPECT_LT(translationError(result.T_w_b, T_w_b_true), 0.005);
  EXPECT_LT(rotationErrorDeg(result.T_w_b, T_w_b_true), 0.1);
  // The IMU over 50 ms pins the velocity: dp = v dt + ..., 5 mm of position noise -> ~0.1 m/s.
  EXPECT_LT((result.v_w_b - cur.v_w_b).norm(), 0.05);
  EXPECT_LT(result.bias.b_g.norm(), 1e-3);
  EXPECT_LT(result.bias.b_a.norm(), 0.05);
  const Eigen::SelfAdjointEigenSolver<Mat6> information(result.pose_information);
  EXPECT_GT(information.eigenvalues().minCoeff(), 0.0);

  // Previous state free under a prior (marginalised last frame): same answer, and the prior keeps
  // the previous pose where its information says.
  PreviousStatePrior prior;
  prior.information.setZero();
  prior.information.topLeftCorner<6, 6>() = 1e6 * Mat6::Identity();
  prior.information.block<3, 3>(6, 6) = 1e4 * Mat3::Identity();
  prior.information.block<3, 3>(9, 9) = 1e6 * Mat3::Identity();
  prior.information.block<3, 3>(12, 12) = 1e4 * Mat3::Identity();
  problem.inertial->prev_prior = prior;
  const PoseOnlyResult with_prior = optimizePose(problem);
  EXPECT_LT(translationError(with_prior.T_w_b, T_w_b_true), 0.005);
  EXPECT_LT(rotationErrorDeg(with_prior.T_w_b, T_w_b_true), 0.1);
  EXPECT_LT((with_prior.v_w_b - cur.v_w_b).norm(), 0.05);
}

// A keyframe whose velocity is not known (the first keyframe of a new map) links the next frame
// with that velocity free: the frame's pose then comes from its few observations alone. When they
// all lie (points on a mover, here as if the camera stood 3 cm to the side), the pose follows them;
// a prior on the free velocity (Tracking.NewMapVelocityPrior: the velocity the IMU carried through
// the loss, with its uncertainty) keeps the IMU's position and velocity (issue 32).
TEST(PoseOnlyProblem, PriorOnAFreePreviousVelocityHoldsTheImuAgainstLyingObservations) {
  std::mt19937 rng(21);
  const ProjectionModel model = testModel();
  const imu::test::AnalyticTrajectory trajectory;
  const double t_prev = 2.0, t_cur = 2.0 + 1.0 / 30.0;
  const imu::NavState prev = trajectory.state(t_prev);
  const imu::NavState cur = trajectory.state(t_cur);
  auto pim = std::make_shared<imu::Preintegrated>(imu::ImuBias{}, imu::ImuNoise());
  pim->integrate(trajectory.samples(t_prev, t_cur, 200.0));
  const SE3 T_w_b_true(cur.R_w_b, cur.p_w_b);
  const SE3 T_w_b_seen = T_w_b_true * SE3(Quat::Identity(), Vec3(0.0, 0.03, 0.0));

  PoseOnlyProblem problem;
  problem.model = model;
  problem.T_w_b_init = T_w_b_true;
  problem.v_w_b_init = cur.v_w_b;
  for (int k = 0; k < 12; ++k) {
    const Vec3 p_w = visiblePoint(rng, model, T_w_b_seen);
    const Vec3 p_c = model.T_c_x * (T_w_b_seen.inverse() * p_w);
    problem.observations.push_back(PoseObservation{p_w, model.camera.project(p_c), p_c.z(), 1.0, 1.0});
  }
  InertialLink link;
  link.T_w_b_prev = SE3(prev.R_w_b, prev.p_w_b);
  link.v_w_b_prev = prev.v_w_b;
  link.pim = pim;
  link.prev_velocity_free = true;
  problem.inertial = link;
  const PoseOnlyResult free_velocity = optimizePose(problem);
  EXPECT_GT(translationError(free_velocity.T_w_b, T_w_b_true), 0.02);
  EXPECT_GT((free_velocity.v_w_b - cur.v_w_b).norm(), 0.5);

  const double sigma_v = 0.02;
  problem.inertial->prev_velocity_information = Mat3::Identity() / (sigma_v * sigma_v);
  const PoseOnlyResult with_prior = optimizePose(problem);
  EXPECT_LT(translationError(with_prior.T_w_b, T_w_b_true), 0.005);
  EXPECT_LT((with_prior.v_w_b - cur.v_w_b).norm(), 0.15);
  // The marginal of a prediction through such a link is finite in position (free: the velocity,
  // and so the position, unconstrained without observations).
  const Mat15 predicted = predictedStateInformation(
      *problem.inertial, InertialState{T_w_b_true, cur.v_w_b, imu::ImuBias{}});
  const Eigen::SelfAdjointEigenSolver<Mat15> eigen(0.5 * (predicted + predicted.transpose()));
  EXPECT_GT(eigen.eigenvalues().minCoeff(), 0.0);
}

// Tracking's information filter over frames: chaining predictedStateInformation frame by frame
// (each frame's marginal the next one's prior) gives the information of one prediction over the
// whole interval from the same fixed start (preintegrations compose), and optimizePose without
// observations reports the same marginal. The bias random walk is made negligible: one prediction
// over the union holds the bias constant over the interval, the chain lets it walk frame to frame
// (with the default walk the chain's velocity variance is ~20 % lower, the correct figure).
TEST(PoseOnlyProblem, ChainedPredictionInformationEqualsOnePredictionOverTheUnion) {
  const imu::test::AnalyticTrajectory trajectory;
  imu::ImuNoise noise;
  noise.gyro_walk_density = 1e-9;
  noise.acc_walk_density = 1e-9;
  const imu::ImuBias bias;
  const double t0 = 1.0, frame_dt = 1.0 / 30.0;
  constexpr int kFrames = 15;
  const std::vector<ImuSample> grid = trajectory.samples(0.5, 2.0, 200.0);
  auto preintegrate = [&](double a, double b) {
    auto pim = std::make_shared<imu::Preintegrated>(bias, noise);
    pim->integrate(imu::samplesInInterval(grid, a, b));
    return pim;
  };
  auto toState = [&](const imu::NavState& nav) {
    return InertialState{SE3(nav.R_w_b, nav.p_w_b), nav.v_w_b, bias};
  };
  imu::NavState state = trajectory.state(t0);
  const imu::NavState start = state;
  std::optional<PreviousStatePrior> prior;
  Mat15 chained = Mat15::Zero();
  for (int k = 0; k < kFrames; ++k) {
    InertialLink link;
    link.T_w_b_prev = SE3(state.R_w_b, state.p_w_b);
    link.v_w_b_prev = state.v_w_b;
    link.bias_prev = bias;
    link.pim = preintegrate(t0 + k * frame_dt, t0 + (k + 1) * frame_dt);
    link.prev_prior = prior;
    const imu::NavState next = imu::predict(state, *link.pim, bias, imu::gravityWorld());
    chained = predictedStateInformation(link, toState(next));
    if (k == kFrames - 1) {
      // optimizePose with no observations: the prediction is the optimum, the same marginal.
      PoseOnlyProblem problem;
      problem.T_w_b_init = SE3(next.R_w_b, next.p_w_b);
      problem.v_w_b_init = next.v_w_b;
      problem.inertial = link;
      const PoseOnlyResult result = optimizePose(problem);
      EXPECT_LT((result.T_w_b.translation() - next.p_w_b).norm(), 1e-9);
      EXPECT_LT((result.state_information - chained).norm(), 1e-6 * chained.norm());
    }
    prior = PreviousStatePrior{chained};
    state = next;
  }
  InertialLink whole;
  whole.T_w_b_prev = SE3(start.R_w_b, start.p_w_b);
  whole.v_w_b_prev = start.v_w_b;
  whole.pim = preintegrate(t0, t0 + kFrames * frame_dt);
  const Mat15 direct = predictedStateInformation(whole, toState(state));
  const Mat9 cov_chained = chained.inverse().topLeftCorner<9, 9>();
  const Mat9 cov_direct = direct.inverse().topLeftCorner<9, 9>();
  EXPECT_LT((cov_chained - cov_direct).norm(), 1e-2 * cov_direct.norm());
  // 0.5 s of accelerometer noise alone: sigma_p ~ sigma_a sqrt(T^3 / 3) per axis.
  const double sigma_p = std::sqrt(cov_direct.block<3, 3>(3, 3).trace() / 3.0);
  const double T = kFrames * frame_dt;
  EXPECT_NEAR(sigma_p, noise.acc_density * std::sqrt(T * T * T / 3.0), 0.3 * noise.acc_density * std::sqrt(T * T * T / 3.0));
}

TEST(PoseOnlyProblem, PoseInformationMatchesObservationCount) {
  // Doubling the observations (same geometry twice) doubles the pose information.
  std::mt19937 rng(14);
  const ProjectionModel model = testModel();
  const SE3 T_w_b_true(so3ExpQuat(Vec3(-0.2, 0.1, 0.3)), Vec3(0.3, 0.2, -0.1));
  PoseOnlyProblem problem;
  problem.model = model;
  problem.T_w_b_init = T_w_b_true;
  for (int k = 0; k < 40; ++k) {
    const Vec3 p_w = visiblePoint(rng, model, T_w_b_true);
    const Vec3 p_c = model.T_c_x * (T_w_b_true.inverse() * p_w);
    problem.observations.push_back(PoseObservation{p_w, model.camera.project(p_c), p_c.z(), 1.0, 1.0});
  }
  const PoseOnlyResult single = optimizePose(problem);
  const std::vector<PoseObservation> once = problem.observations;
  problem.observations.insert(problem.observations.end(), once.begin(), once.end());
  const PoseOnlyResult twice = optimizePose(problem);
  EXPECT_EQ(single.num_inliers, 40);
  EXPECT_EQ(twice.num_inliers, 80);
  EXPECT_LT((twice.pose_information - 2.0 * single.pose_information).norm(),
            1e-6 * single.pose_information.norm());
  EXPECT_LT(translationError(single.T_w_b, T_w_b_true), 1e-9);
}

TEST(LocalBundleAdjust, VisualInertialWindowConvergesToGroundTruth) {
  std::mt19937 rng(13);
  std::normal_distribution<double> normal(0.0, 1.0);
  const ProjectionModel model = testModel();
  const imu::test::AnalyticTrajectory trajectory;
  const imu::ImuBias true_bias{Vec3(0.003, -0.002, 0.004), Vec3(0.04, -0.03, 0.05)};
  constexpr int kNumKeyFrames = 5;
  constexpr double kSpacing_s = 0.3;

  LocalBaProblem problem;
  problem.model = model;
  std::vector<SE3> T_w_b_true;
  std::vector<imu::NavState> states;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    const double t = 1.0 + kSpacing_s * k;
    states.push_back(trajectory.state(t));
    T_w_b_true.emplace_back(states.back().R_w_b, states.back().p_w_b);
    BaKeyFrame kf;
    kf.id = 100 + k;
    kf.fixed = k == 0;  // gauge
    const Vec3 dphi = k == 0 ? Vec3::Zero() : Vec3(0.01 * normal(rng), 0.01 * normal(rng), 0.01 * normal(rng));
    const Vec3 dp = k == 0 ? Vec3::Zero() : Vec3(0.03 * normal(rng), 0.03 * normal(rng), 0.03 * normal(rng));
    kf.T_w_b = SE3(T_w_b_true.back().quaternion() * so3ExpQuat(dphi), T_w_b_true.back().translation() + dp);
    kf.v_w_b = states.back().v_w_b + (k == 0 ? Vec3::Zero() : Vec3(0.1, -0.1, 0.1));
    kf.bias = k == 0 ? true_bias : imu::ImuBias{};
    problem.keyframes.push_back(kf);
    if (k > 0) {
      auto pim = std::make_shared<imu::Preintegrated>(imu::ImuBias{}, imu::ImuNoise());
      pim->integrate(trajectory.samples(t - kSpacing_s, t, 200.0, true_bias));
      problem.inertial.push_back(BaInertialLink{100 + k - 1, 100 + k, pim});
    }
  }
  // 200 points, 40 seeded from each keyframe, observed (noise-free) where they project.
  std::vector<Vec3> points_true;
  for (int m = 0; m < 200; ++m) {
    points_true.push_back(visiblePoint(rng, model, T_w_b_true[static_cast<size_t>(m / 40)]));
    problem.points.push_back(BaPoint{m, points_true.back() + 0.05 * Vec3(normal(rng), normal(rng), normal(rng))});
  }
  int num_observations = 0;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    for (int m = 0; m < 200; ++m) {
      const Vec3 p_c = model.T_c_x * (T_w_b_true[static_cast<size_t>(k)].inverse() * points_true[static_cast<size_t>(m)]);
      if (p_c.z() < 0.3) continue;
      const Vec2 uv = model.camera.project(p_c);
      if (!model.camera.isInImage(uv)) continue;
      BaObservation obs;
      obs.keyframe_id = 100 + k;
      obs.point_id = m;
      obs.uv = uv;
      // Every fourth point has depth only in the keyframe that seeded it (2-D edges elsewhere).
      obs.depth_m = (m % 4 == 0 && m / 40 != k) ? 0.0 : p_c.z();
      problem.observations.push_back(obs);
      ++num_observations;
    }
  }
  ASSERT_GT(num_observations, 400);

  const LocalBaResult result = localBundleAdjust(problem);
  for (int k = 1; k < kNumKeyFrames; ++k) {
    const BaKeyFrame& kf = result.keyframes[static_cast<size_t>(k)];
    EXPECT_LT(translationError(kf.T_w_b, T_w_b_true[static_cast<size_t>(k)]), 1e-3) << "keyframe " << k;
    EXPECT_LT(rotationErrorDeg(kf.T_w_b, T_w_b_true[static_cast<size_t>(k)]), 0.01) << "keyframe " << k;
    EXPECT_LT((kf.v_w_b - states[static_cast<size_t>(k)].v_w_b).norm(), 0.01) << "keyframe " << k;
  }
  double max_point_error = 0.0;
  for (size_t m = 0; m < points_true.size(); ++m)
    max_point_error = std::max(max_point_error, (result.points[m].p_w - points_true[m]).norm());
  EXPECT_LT(max_point_error, 1e-3);
  for (bool inlier : result.inliers) EXPECT_TRUE(inlier);
  // Biases (of keyframe 1, the first free one) recovered to first-order-correction accuracy.
  EXPECT_LT((result.keyframes[1].bias.b_g - true_bias.b_g).norm(), 1e-3);
  EXPECT_LT((result.keyframes[1].bias.b_a - true_bias.b_a).norm(), 0.02);
}

TEST(ImuInitialization, RecoversGravityDirectionAndBiasesFromKnownPoses) {
  const imu::test::AnalyticTrajectory trajectory;
  const imu::ImuBias true_bias{Vec3(0.01, -0.02, 0.015), Vec3(0.1, -0.05, 0.08)};
  // The map frame m is the gravity-aligned frame rotated by R_m_w (yaw, pitch and roll).
  const Mat3 R_m_w = so3Exp(Vec3(0.2, -0.15, 1.1));
  constexpr int kNumKeyFrames = 10;
  constexpr double kSpacing_s = 0.25;
  ImuInitProblem problem;
  std::vector<Vec3> v_m_true;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    const double t = 0.5 + kSpacing_s * k;
    const imu::NavState s = trajectory.state(t);
    problem.T_w_b.emplace_back(R_m_w * s.R_w_b, R_m_w * s.p_w_b);
    v_m_true.push_back(R_m_w * s.v_w_b);
    if (k > 0) {
      auto pim = std::make_shared<imu::Preintegrated>(imu::ImuBias{}, imu::ImuNoise());
      pim->integrate(trajectory.samples(t - kSpacing_s, t, 200.0, true_bias));
      problem.pims.push_back(pim);
    }
  }
  const Vec3 gravity_dir_true = R_m_w * Vec3(0.0, 0.0, -1.0);

  const ImuInitResult linear = linearImuInit(problem);
  const ImuInitResult result = initializeImu(problem);
  const double angle_linear_deg =
      std::acos(std::min(1.0, linear.g_w.normalized().dot(gravity_dir_true))) * kRadToDeg;
  const double angle_deg = std::acos(std::min(1.0, result.g_w.normalized().dot(gravity_dir_true))) * kRadToDeg;
  EXPECT_LT(angle_linear_deg, 5.0);  // biases ignored in the linear guess
  EXPECT_LT(angle_deg, 0.05);
  EXPECT_LT((result.bias.b_g - true_bias.b_g).norm(), 5e-4);
  EXPECT_LT((result.bias.b_a - true_bias.b_a).norm(), 0.01);
  for (int k = 0; k < kNumKeyFrames; ++k)
    EXPECT_LT((result.v_w_b[static_cast<size_t>(k)] - v_m_true[static_cast<size_t>(k)]).norm(), 0.01) << k;
}

// With the gravity already known (a loaded map's, ImuInitProblem::known_R_w_g) the window only
// estimates velocities and biases: the gravity comes back exactly as given, and on a short window,
// where a horizontal accelerometer bias trades with a tilt of gravity, the bias is found better
// than with the gravity free (localisation only re-estimates the biases this way).
TEST(ImuInitialization, KnownGravityIsHeldAndPinsTheAccelerometerBias) {
  const imu::test::AnalyticTrajectory trajectory;
  const imu::ImuBias true_bias{Vec3(0.004, -0.003, 0.002), Vec3(0.08, -0.06, 0.03)};
  constexpr int kNumKeyFrames = 5;
  constexpr double kSpacing_s = 0.25;
  ImuInitProblem problem;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    const double t = 0.5 + kSpacing_s * k;
    const imu::NavState s = trajectory.state(t);
    problem.T_w_b.emplace_back(s.R_w_b, s.p_w_b);
    if (k > 0) {
      auto pim = std::make_shared<imu::Preintegrated>(imu::ImuBias{}, imu::ImuNoise());
      pim->integrate(trajectory.samples(t - kSpacing_s, t, 200.0, true_bias));
      problem.pims.push_back(pim);
    }
  }
  problem.gyro_bias_prior_information = 1.0;
  problem.acc_bias_prior_information = 1.0;
  const ImuInitResult free_gravity = initializeImu(problem);
  problem.known_R_w_g = Mat3::Identity();  // the analytic trajectory's world is gravity-aligned
  const ImuInitResult known = initializeImu(problem);
  EXPECT_LT((known.g_w - Vec3(0.0, 0.0, -problem.gravity_m_s2)).norm(), 1e-12);
  const double free_error = (free_gravity.bias.b_a - true_bias.b_a).norm();
  const double known_error = (known.bias.b_a - true_bias.b_a).norm();
  EXPECT_LT(known_error, 0.01);
  EXPECT_LE(known_error, free_error + 1e-4) << "free " << free_error << ", known " << known_error;
  EXPECT_LT((known.bias.b_g - true_bias.b_g).norm(), 5e-4);
  EXPECT_TRUE(known.acceleration_covariance_w.allFinite());
}

// The posterior acceleration covariance of the inertial-only initialisation is consistent with its
// real error: over independent noise draws the normalised squared error of the world acceleration a
// prediction integrates (bias and gravity jointly) averages the 3 of a chi-square with 3 degrees of
// freedom, and a longer window is much better known (the loss policy trusts the IMU accordingly).
TEST(ImuInitialization, AccelerationCovarianceMatchesTheErrorOfTheEstimate) {
  const imu::test::AnalyticTrajectory trajectory;
  const imu::ImuBias true_bias{Vec3(0.002, -0.003, 0.001), Vec3(0.03, -0.02, 0.01)};
  imu::ImuNoise noise;  // the simulator's calibration (calib.yaml)
  noise.gyro_density = 1e-3;
  noise.acc_density = 1e-2;
  noise.gyro_walk_density = 1e-5;
  noise.acc_walk_density = 2e-4;
  const Vec3 g_true = imu::gravityFromRotation(Mat3::Identity());
  auto run = [&](double span_s, std::mt19937& rng, Mat3* covariance) {
    // Keyframes every 0.2 s (a whole number of 200 Hz samples), as before the initialisation.
    constexpr double kSpacing_s = 0.2;
    const int num_keyframes = static_cast<int>(std::lround(span_s / kSpacing_s)) + 1;
    const double spacing_s = kSpacing_s;
    ImuInitProblem problem;
    for (int k = 0; k < num_keyframes; ++k) {
      const double t = 0.5 + spacing_s * k;
      const imu::NavState s = trajectory.state(t);
      problem.T_w_b.emplace_back(s.R_w_b, s.p_w_b);
      if (k > 0) {
        auto pim = std::make_shared<imu::Preintegrated>(imu::ImuBias{}, noise);
        pim->integrate(trajectory.samples(t - spacing_s, t, 200.0, true_bias, &noise, &rng));
        problem.pims.push_back(pim);
      }
    }
    const BiasPriorInformation prior = biasPriorInformation(noise, span_s, 1.0);
    problem.gyro_bias_prior_information = prior.gyro;
    problem.acc_bias_prior_information = prior.acc;
    const ImuInitResult result = initializeImu(problem);
    *covariance = result.acceleration_covariance_w;
    // a_w = R_w_b (f - b_a) + g_w: the error of the world acceleration a prediction integrates.
    return Vec3(-problem.T_w_b.back().rotationMatrix() * (result.bias.b_a - true_bias.b_a) + result.g_w - g_true);
  };
  std::mt19937 rng(21);
  constexpr int kDraws = 30;
  double nees = 0.0;
  double sigma_short = 0.0;
  for (int draw = 0; draw < kDraws; ++draw) {
    Mat3 covariance;
    const Vec3 error = run(1.8, rng, &covariance);
    ASSERT_TRUE(covariance.allFinite());
    nees += error.dot(covariance.ldlt().solve(error)) / kDraws;
    sigma_short = accelerationSigma(covariance);
  }
  // Mean of 30 chi-square(3) draws: 3 with a standard deviation of sqrt(6 / 30) = 0.45.
  EXPECT_GT(nees, 3.0 - 3.0 * 0.45);
  EXPECT_LT(nees, 3.0 + 3.0 * 0.45);
  Mat3 covariance_long;
  run(5.4, rng, &covariance_long);
  // Three times the window at the same keyframe rate: known better (2.3 times here; the joint
  // bias / gravity block is limited by the attitudes the window visits, not only by its length).
  EXPECT_LT(accelerationSigma(covariance_long), sigma_short / 2.0);
  EXPECT_GT(sigma_short, 1e-3);
  EXPECT_TRUE(std::isinf(accelerationSigma(Mat3::Constant(std::numeric_limits<double>::infinity()))));
}

TEST(LocalBundleAdjust, VisualOnlyRejectsCorruptedObservations) {
  std::mt19937 rng(15);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const ProjectionModel model = testModel();
  std::vector<SE3> T_w_b_true;
  LocalBaProblem problem;
  problem.model = model;
  for (int k = 0; k < 4; ++k) {
    T_w_b_true.emplace_back(so3ExpQuat(Vec3(0.0, 0.0, 0.05 * k)), Vec3(0.2 * k, 0.1 * k, 0.0));
    BaKeyFrame kf;
    kf.id = k;
    kf.fixed = k == 0;
    kf.T_w_b = k == 0 ? T_w_b_true.back()
                      : T_w_b_true.back() * SE3(so3ExpQuat(0.01 * Vec3(normal(rng), normal(rng), normal(rng))),
                                                0.03 * Vec3(normal(rng), normal(rng), normal(rng)));
    problem.keyframes.push_back(kf);
  }
  std::vector<Vec3> points_true;
  for (int m = 0; m < 150; ++m) {
    points_true.push_back(visiblePoint(rng, model, T_w_b_true[0]));
    problem.points.push_back(BaPoint{m, points_true.back() + 0.03 * Vec3(normal(rng), normal(rng), normal(rng))});
  }
  std::vector<bool> corrupted;
  for (int k = 0; k < 4; ++k) {
    for (int m = 0; m < 150; ++m) {
      const Vec3 p_c = model.T_c_x * (T_w_b_true[static_cast<size_t>(k)].inverse() * points_true[static_cast<size_t>(m)]);
      const Vec2 uv = model.camera.project(p_c);
      if (p_c.z() < 0.3 || !model.camera.isInImage(uv)) continue;
      BaObservation obs{k, m, uv, p_c.z(), 1.0, m % 3 == 0 ? 0.5 : 1.0};
      const bool corrupt = m % 10 == 7 && k == 1 + (m / 10) % 3;  // one bad observation per point
      if (corrupt) obs.uv += Vec2(30.0 + 40.0 * uniform(rng), -30.0 - 40.0 * uniform(rng));
      problem.observations.push_back(obs);
      corrupted.push_back(corrupt);
    }
  }
  const LocalBaResult result = localBundleAdjust(problem);
  for (int k = 1; k < 4; ++k) {
    EXPECT_LT(translationError(result.keyframes[static_cast<size_t>(k)].T_w_b, T_w_b_true[static_cast<size_t>(k)]), 1e-3);
    EXPECT_LT(rotationErrorDeg(result.keyframes[static_cast<size_t>(k)].T_w_b, T_w_b_true[static_cast<size_t>(k)]), 0.01);
  }
  // Every corrupted observation is rejected; nearly all clean ones are kept. A few clean ones of the
  // corrupted points may go too: the virtual baseline (bf = 41.6 px m) constrains depth weakly
  // (~5 px per m at 3 m), so the bounded Huber pull of a 100 px outlier can shift such a point
  // along its ray until its clean observations fail the gate, as in ORB-SLAM.
  int clean = 0, clean_kept = 0;
  for (size_t n = 0; n < corrupted.size(); ++n) {
    if (corrupted[n]) {
      EXPECT_FALSE(result.inliers[n]) << "observation " << n;
    } else {
      ++clean;
      if (result.inliers[n]) ++clean_kept;
    }
  }
  EXPECT_GE(clean_kept, clean - 12);
  // Residuals for the Eq. 53 updates: unweighted, so a weight-0.5 clean observation is near zero
  // and a corrupted one is large.
  ASSERT_EQ(result.residual_chi2.size(), corrupted.size());
  for (size_t n = 0; n < corrupted.size(); ++n) {
    if (corrupted[n]) {
      EXPECT_GT(result.residual_chi2[n], 100.0) << "observation " << n;
    }
  }
}

// Poses on a circle of radius 3 m, heading along the tangent.
std::vector<SE3> circlePoses(int count) {
  std::vector<SE3> poses;
  for (int k = 0; k < count; ++k) {
    const double angle = 2.0 * M_PI * k / count;
    poses.emplace_back(so3ExpQuat(Vec3(0.0, 0.0, angle + M_PI / 2)),
                       Vec3(3.0 * std::cos(angle), 3.0 * std::sin(angle), 0.1 * std::sin(3 * angle)));
  }
  return poses;
}

TEST(PoseGraph, LoopEdgeRemovesOdometryDrift) {
  std::mt19937 rng(16);
  std::normal_distribution<double> normal(0.0, 1.0);
  constexpr int kCount = 16;
  const std::vector<SE3> truth = circlePoses(kCount);
  std::vector<PoseGraphEdge> edges;
  std::vector<PoseGraphNode> nodes;
  nodes.push_back(PoseGraphNode{0, truth[0], true});
  for (int k = 0; k + 1 < kCount; ++k) {
    // Odometry with a systematic yaw error (0.3 deg per step) and 5 mm noise.
    const SE3 noise(so3ExpQuat(Vec3(0.0, 0.0, 0.3 / kRadToDeg)),
                    0.005 * Vec3(normal(rng), normal(rng), normal(rng)));
    const SE3 T_i_j = truth[static_cast<size_t>(k)].inverse() * truth[static_cast<size_t>(k + 1)] * noise;
    edges.push_back(PoseGraphEdge{k, k + 1, T_i_j, Mat6::Identity()});
    nodes.push_back(PoseGraphNode{k + 1, nodes.back().T_w_b * T_i_j, false});
  }
  PoseGraphEdge loop{kCount - 1, 0, truth[kCount - 1].inverse() * truth[0], 100.0 * Mat6::Identity()};
  edges.push_back(loop);
  const double drift_before = translationError(nodes.back().T_w_b, truth.back());
  const PoseGraphResult result = optimizePoseGraph(nodes, edges);
  double drift_after = 0.0;
  for (int k = 0; k < kCount; ++k)
    drift_after = std::max(drift_after, translationError(result.nodes[static_cast<size_t>(k)].T_w_b, truth[static_cast<size_t>(k)]));
  EXPECT_GT(drift_before, 0.2);
  EXPECT_LT(drift_after, 0.25 * drift_before);
  EXPECT_TRUE(result.nodes[0].T_w_b.translation() == truth[0].translation());  // fixed node untouched
}

TEST(PoseGraph, ConsistentMeasurementsRecoverPosesFromPerturbedStart) {
  std::mt19937 rng(17);
  std::normal_distribution<double> normal(0.0, 1.0);
  const std::vector<SE3> truth = circlePoses(12);
  std::vector<PoseGraphNode> nodes;
  std::vector<PoseGraphEdge> edges;
  for (int k = 0; k < 12; ++k) {
    const SE3 perturbation(so3ExpQuat(0.05 * Vec3(normal(rng), normal(rng), normal(rng))),
                           0.2 * Vec3(normal(rng), normal(rng), normal(rng)));
    nodes.push_back(PoseGraphNode{10 * k, k == 0 ? truth[0] : truth[static_cast<size_t>(k)] * perturbation, k == 0});
    const int j = (k + 1) % 12;
    edges.push_back(PoseGraphEdge{10 * k, 10 * j, truth[static_cast<size_t>(k)].inverse() * truth[static_cast<size_t>(j)], Mat6::Identity()});
  }
  const PoseGraphResult result = optimizePoseGraph(nodes, edges);
  for (int k = 0; k < 12; ++k) {
    EXPECT_LT(translationError(result.nodes[static_cast<size_t>(k)].T_w_b, truth[static_cast<size_t>(k)]), 1e-6);
    EXPECT_LT(rotationErrorDeg(result.nodes[static_cast<size_t>(k)].T_w_b, truth[static_cast<size_t>(k)]), 1e-5);
  }
}

}  // namespace
}  // namespace ltlo::optim
