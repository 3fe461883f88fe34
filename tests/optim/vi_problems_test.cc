// Issue 10's optimisation problems with known gravity: the 4-DoF pose graph (Jacobians, roll and
// pitch left untouched, a yaw + translation drift removed), the swing-twist helpers, and the
// visual-inertial BA with the gravity direction as an unknown (the IMU-initialisation refinement)
// against the inertial-only initialisation on the same generated window.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>

#include "common/analytic_trajectory.h"
#include "common/numeric_jacobian.h"
#include "ltlo/core/lie.h"
#include "ltlo/optim/bundle_adjust.h"
#include "ltlo/optim/pose_graph.h"
#include "ltlo/optim/yaw_pose_edges.h"

namespace ltlo::optim {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

double angleDeg(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)) * kRadToDeg; }

// The body's up axis in its own frame: what roll and pitch relative to gravity determine.
Vec3 upInBody(const SE3& T_w_b, const Vec3& up_w) { return T_w_b.rotationMatrix().transpose() * up_w; }

// A gravity direction well away from the axes, so nothing below works by accident on z.
Vec3 tiltedGravity() { return 9.81 * Vec3(0.3, -0.2, -1.0).normalized(); }

TEST(YawPoseEdges, RelativePoseJacobiansMatchNumeric) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Vec3 up_w = -tiltedGravity().normalized();
  for (int trial = 0; trial < 5; ++trial) {
    VertexYawPose pose_i(0, SE3(so3ExpQuat(Vec3(u(rng), u(rng), u(rng))), Vec3(u(rng), u(rng), u(rng))), up_w);
    VertexYawPose pose_j(1, SE3(so3ExpQuat(Vec3(u(rng), u(rng), u(rng))), Vec3(u(rng), u(rng), u(rng))), up_w);
    EdgeYawRelativePose edge;
    edge.setVertex(0, &pose_i);
    edge.setVertex(1, &pose_j);
    // A measurement near the current relative pose (as in a pose graph), not equal to it.
    edge.setMeasurement(pose_i.estimate().inverse() * pose_j.estimate() *
                        SE3(so3ExpQuat(0.1 * Vec3(u(rng), u(rng), u(rng))), 0.1 * Vec3(u(rng), u(rng), u(rng))));
    for (int v = 0; v < 2; ++v) {
      VertexYawPose& vertex = v == 0 ? pose_i : pose_j;
      const SE3 x0 = vertex.estimate();
      edge.computeError();
      edge.linearizeOplus();
      const Eigen::Matrix<double, 6, 4> analytic = v == 0 ? edge.jacobian<0>() : edge.jacobian<1>();
      const Eigen::Matrix<double, 6, 4> numeric = test::numericJacobianOnManifold<4>(
          [&](const SE3& x) -> Vec6 {
            vertex.setEstimate(x);
            edge.computeError();
            return edge.error();
          },
          x0, [&](const SE3& x, const Vec4& delta) { return vertex.plus(x, delta); });
      vertex.setEstimate(x0);
      EXPECT_LT((analytic - numeric).norm(), 1e-6 * std::max(1.0, numeric.norm())) << "trial " << trial << " vertex " << v;
    }
  }
}

TEST(YawPoseEdges, VertexTurnsAboutGravityOnly) {
  const Vec3 up_w = -tiltedGravity().normalized();
  VertexYawPose pose(0, SE3(so3ExpQuat(Vec3(0.3, -0.5, 1.2)), Vec3(1.0, 2.0, 3.0)), up_w);
  const SE3 moved = pose.plus(pose.estimate(), Vec4(0.7, 0.1, -0.2, 0.3));
  EXPECT_LT(angleDeg(upInBody(moved, up_w), upInBody(pose.estimate(), up_w)), 1e-9);
  EXPECT_LT((moved.translation() - Vec3(1.1, 1.8, 3.3)).norm(), 1e-12);
  // The turn is 0.7 rad about up_w.
  const Vec3 turn = so3Log(moved.rotationMatrix() * pose.estimate().rotationMatrix().transpose());
  EXPECT_LT((turn - 0.7 * up_w).norm(), 1e-9);
}

TEST(YawPoseEdges, TwistAndFourDofCorrection) {
  const Vec3 g_w = tiltedGravity();
  const Vec3 up_w = -g_w.normalized();
  // A pure turn about the axis is kept; a tilt is dropped.
  const Quat yaw = so3ExpQuat(0.4 * up_w);
  EXPECT_LT(so3Log(twistAbout(yaw, g_w).conjugate() * yaw).norm(), 1e-12);
  const Vec3 tilt_axis = up_w.cross(Vec3(1.0, 0.0, 0.0)).normalized();
  const Quat tilted = yaw * so3ExpQuat(0.05 * tilt_axis);
  const Quat twist = twistAbout(tilted, g_w);
  const Vec3 twist_log = so3Log(twist);
  EXPECT_LT(twist_log.cross(up_w).norm(), 1e-12);  // about the axis
  EXPECT_NEAR(twist_log.dot(up_w), 0.4, 2e-3);     // the tilt barely changes the yaw
  EXPECT_LT(so3Log(twistAbout(so3ExpQuat(M_PI * tilt_axis), g_w)).norm(), 1e-9);  // half turn across: none
  // The 4-DoF correction keeps gravity and takes the anchor where the full correction does.
  const SE3 full(tilted, Vec3(0.2, -0.1, 0.3));
  const Vec3 anchor(1.0, 2.0, -0.5);
  const SE3 reduced = fourDofCorrection(full, g_w, anchor);
  EXPECT_LT((reduced * anchor - full * anchor).norm(), 1e-12);
  EXPECT_LT(angleDeg(reduced.rotationMatrix() * up_w, up_w), 1e-9);
}

// Poses around a loop (radius 3 m) with roll and pitch relative to gravity, heading along the loop.
std::vector<SE3> tiltedLoop(int count, const Vec3& g_w) {
  const Mat3 R_w_g = imu::gravityRotationFromDirection(g_w);  // gravity frame -> w
  std::vector<SE3> poses;
  for (int k = 0; k < count; ++k) {
    const double angle = 2.0 * M_PI * k / count;
    const Mat3 R_g_b = so3Exp(Vec3(0.0, 0.0, angle + M_PI / 2)) * so3Exp(Vec3(0.1 * std::sin(2 * angle), 0.08, 0.0));
    const Vec3 p_g(3.0 * std::cos(angle), 3.0 * std::sin(angle), 0.2 * std::sin(3 * angle));
    poses.emplace_back(R_w_g * R_g_b, R_w_g * p_g);
  }
  return poses;
}

TEST(PoseGraph4Dof, RemovesYawAndTranslationDriftAndKeepsRollAndPitch) {
  std::mt19937 rng(18);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Vec3 g_w = tiltedGravity();
  const Vec3 up_w = -g_w.normalized();
  constexpr int kCount = 20;
  const std::vector<SE3> truth = tiltedLoop(kCount, g_w);
  // Odometry drifting in yaw about gravity (0.4 deg per step) and translation (1 cm per step
  // sideways, 3 mm noise); each node's roll and pitch are its true ones (gravity makes them
  // observable), its yaw and position come from the drifting odometry.
  std::vector<PoseGraphNode> nodes{PoseGraphNode{0, truth[0], true}};
  std::vector<PoseGraphEdge> edges;
  for (int k = 0; k + 1 < kCount; ++k) {
    const SE3 T_i_j = truth[static_cast<size_t>(k)].inverse() * truth[static_cast<size_t>(k + 1)];
    edges.push_back(PoseGraphEdge{k, k + 1, T_i_j, Mat6::Identity()});
    const SE3 drift_w(so3ExpQuat(up_w * (0.4 / kRadToDeg) * (k + 1)),
                      Vec3(0.01 * (k + 1), 0.0, 0.0) + 0.003 * Vec3(normal(rng), normal(rng), normal(rng)));
    const SE3& T_true = truth[static_cast<size_t>(k + 1)];
    nodes.push_back(PoseGraphNode{k + 1, SE3(drift_w.quaternion() * T_true.quaternion(),
                                             T_true.translation() + drift_w.translation()), false});
  }
  edges.push_back(PoseGraphEdge{kCount - 1, 0, truth[kCount - 1].inverse() * truth[0], 100.0 * Mat6::Identity()});

  double drift_before = 0.0;
  for (int k = 0; k < kCount; ++k)
    drift_before = std::max(drift_before, (nodes[static_cast<size_t>(k)].T_w_b.translation() - truth[static_cast<size_t>(k)].translation()).norm());
  const PoseGraphResult result = optimizePoseGraph4Dof(nodes, edges, g_w);
  double drift_after = 0.0, tilt_change_deg = 0.0, yaw_error_deg = 0.0;
  for (int k = 0; k < kCount; ++k) {
    const SE3& before = nodes[static_cast<size_t>(k)].T_w_b;
    const SE3& after = result.nodes[static_cast<size_t>(k)].T_w_b;
    drift_after = std::max(drift_after, (after.translation() - truth[static_cast<size_t>(k)].translation()).norm());
    tilt_change_deg = std::max(tilt_change_deg, angleDeg(upInBody(after, up_w), upInBody(before, up_w)));
    yaw_error_deg = std::max(yaw_error_deg, so3Log(after.quaternion() * truth[static_cast<size_t>(k)].quaternion().conjugate()).norm() * kRadToDeg);
  }
  std::printf("[ POSE4DOF ] drift %.4f -> %.4f m, yaw error after %.4f deg, roll/pitch change %.2e deg, chi2 %.3g -> %.3g\n",
              drift_before, drift_after, yaw_error_deg, tilt_change_deg, result.summary.initial_chi2,
              result.summary.final_chi2);
  EXPECT_GT(drift_before, 0.15);
  EXPECT_LT(drift_after, 0.1 * drift_before);
  EXPECT_LT(yaw_error_deg, 0.5);  // 7.6 deg of accumulated yaw drift before
  EXPECT_LT(tilt_change_deg, 1e-9);
  EXPECT_TRUE(result.nodes[0].T_w_b.translation() == truth[0].translation());  // the fixed node
}

// ---- the IMU-initialisation refinement ----

ProjectionModel testModel() {
  ProjectionModel model;
  model.camera = PinholeCamera(520.0, 520.0, 319.5, 239.5, 640, 480);
  Mat3 R_b_c;  // camera along the body x axis
  R_b_c << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  model.T_c_x = SE3(R_b_c, Vec3(0.05, -0.02, 0.01)).inverse();
  model.bf_px_m = 520.0 * 0.08;
  return model;
}

Vec3 visiblePoint(std::mt19937& rng, const ProjectionModel& model, const SE3& T_w_b) {
  std::uniform_real_distribution<double> u(20.0, 620.0), v(20.0, 460.0), depth(1.5, 4.0);
  return T_w_b * (model.T_c_x.inverse() * model.camera.backProject(Vec2(u(rng), v(rng)), depth(rng)));
}

/// 30 points in front of each keyframe (true poses T_true), started 2 cm (sigma) off the truth and
/// observed with 1 px noise and RGB-D depth by every keyframe that sees them; returns the true points.
std::vector<Vec3> addObservedPoints(LocalBaProblem& problem, const std::vector<SE3>& T_true,
                                    const ProjectionModel& model, std::mt19937& rng,
                                    std::normal_distribution<double>& normal) {
  const int num_keyframes = static_cast<int>(T_true.size());
  std::vector<Vec3> points_true;
  for (int m = 0; m < 30 * num_keyframes; ++m) {
    points_true.push_back(visiblePoint(rng, model, T_true[static_cast<size_t>(m / 30)]));
    problem.points.push_back(BaPoint{m, points_true.back() + 0.02 * Vec3(normal(rng), normal(rng), normal(rng))});
  }
  for (int k = 0; k < num_keyframes; ++k) {
    for (int m = 0; m < static_cast<int>(points_true.size()); ++m) {
      const Vec3 p_c = model.T_c_x * (T_true[static_cast<size_t>(k)].inverse() * points_true[static_cast<size_t>(m)]);
      if (p_c.z() < 0.3) continue;
      const Vec2 uv = model.camera.project(p_c) + Vec2(normal(rng), normal(rng));
      if (!model.camera.isInImage(uv)) continue;
      BaObservation obs;
      obs.keyframe_id = k;
      obs.point_id = m;
      obs.uv = uv;
      const double u_r = model.projectRgbd(p_c).z() + normal(rng);
      obs.depth_m = model.bf_px_m / (uv.x() - u_r);
      problem.observations.push_back(obs);
    }
  }
  return points_true;
}

TEST(ImuRefinement, VisualInertialBaImprovesGravityAndBiasesOverInertialOnly) {
  // A 5 s window of 21 keyframes on the analytic trajectory in a map frame m turned away from
  // gravity; IMU readings with the simulator's noise densities and a constant bias; keyframe poses
  // with tracking-like errors (1.5 cm, 0.3 deg); points seen with 1 px noise and depth.
  std::mt19937 rng(21);
  std::normal_distribution<double> normal(0.0, 1.0);
  const ProjectionModel model = testModel();
  const imu::test::AnalyticTrajectory trajectory;
  const imu::ImuBias true_bias{Vec3(0.002, -0.003, 0.0015), Vec3(0.04, -0.03, 0.05)};
  imu::ImuNoise noise;
  noise.gyro_density = 1e-3;
  noise.acc_density = 1e-2;
  noise.gyro_walk_density = 1e-5;
  noise.acc_walk_density = 2e-4;
  const Mat3 R_m_w = so3Exp(Vec3(0.1, -0.15, 0.9));
  const Vec3 gravity_dir_true = R_m_w * Vec3(0.0, 0.0, -1.0);
  constexpr int kNumKeyFrames = 21;
  constexpr double kSpacing_s = 0.25;

  std::vector<SE3> T_true;
  std::vector<Vec3> v_true;
  std::vector<std::shared_ptr<const imu::Preintegrated>> pims;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    const double t = 0.5 + kSpacing_s * k;
    const imu::NavState s = trajectory.state(t);
    T_true.emplace_back(R_m_w * s.R_w_b, R_m_w * s.p_w_b);
    v_true.push_back(R_m_w * s.v_w_b);
    if (k > 0) {
      auto pim = std::make_shared<imu::Preintegrated>(imu::ImuBias{}, noise);
      pim->integrate(trajectory.samples(t - kSpacing_s, t, 200.0, true_bias, &noise, &rng));
      pims.push_back(pim);
    }
  }
  std::vector<SE3> T_tracked{T_true[0]};
  for (int k = 1; k < kNumKeyFrames; ++k) {
    T_tracked.push_back(SE3(T_true[static_cast<size_t>(k)].quaternion() *
                                so3ExpQuat((0.3 / kRadToDeg) * Vec3(normal(rng), normal(rng), normal(rng))),
                            T_true[static_cast<size_t>(k)].translation() + 0.015 * Vec3(normal(rng), normal(rng), normal(rng))));
  }
  const double window_s = kSpacing_s * (kNumKeyFrames - 1);
  const BiasPriorInformation prior = biasPriorInformation(noise, window_s, 1.0);

  // Inertial-only initialisation on the tracked poses.
  ImuInitProblem init;
  init.T_w_b = T_tracked;
  init.pims = pims;
  init.gyro_bias_prior_information = prior.gyro;
  init.acc_bias_prior_information = prior.acc;
  const ImuInitResult inertial_only = initializeImu(init);

  // The refinement: poses, velocities, per-keyframe biases, points and gravity direction together.
  LocalBaProblem problem;
  problem.model = model;
  problem.estimate_gravity = true;
  problem.g_w = inertial_only.g_w;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    BaKeyFrame kf;
    kf.id = k;
    kf.T_w_b = T_tracked[static_cast<size_t>(k)];
    kf.v_w_b = inertial_only.v_w_b[static_cast<size_t>(k)];
    kf.bias = inertial_only.bias;
    kf.fixed = k == 0;  // gauge: its pose only
    kf.fixed_pose_only = true;
    problem.keyframes.push_back(kf);
    if (k > 0) problem.inertial.push_back(BaInertialLink{k - 1, k, pims[static_cast<size_t>(k - 1)]});
  }
  problem.bias_priors.push_back(BaBiasPrior{0, imu::ImuBias(), prior.gyro, prior.acc});
  const std::vector<Vec3> points_true = addObservedPoints(problem, T_true, model, rng, normal);
  ASSERT_GT(problem.observations.size(), 3u * points_true.size());
  const LocalBaResult refined = localBundleAdjust(problem);

  const double gravity_before_deg = angleDeg(inertial_only.g_w, gravity_dir_true);
  const double gravity_after_deg = angleDeg(refined.g_w, gravity_dir_true);
  const imu::ImuBias& refined_bias = refined.keyframes[kNumKeyFrames / 2].bias;
  const double b_a_before = (inertial_only.bias.b_a - true_bias.b_a).norm();
  const double b_a_after = (refined_bias.b_a - true_bias.b_a).norm();
  const double b_g_before = (inertial_only.bias.b_g - true_bias.b_g).norm();
  const double b_g_after = (refined_bias.b_g - true_bias.b_g).norm();
  double pose_before = 0.0, pose_after = 0.0, velocity_after = 0.0;
  for (int k = 1; k < kNumKeyFrames; ++k) {
    pose_before = std::max(pose_before, (T_tracked[static_cast<size_t>(k)].translation() - T_true[static_cast<size_t>(k)].translation()).norm());
    pose_after = std::max(pose_after, (refined.keyframes[static_cast<size_t>(k)].T_w_b.translation() - T_true[static_cast<size_t>(k)].translation()).norm());
    velocity_after = std::max(velocity_after, (refined.keyframes[static_cast<size_t>(k)].v_w_b - v_true[static_cast<size_t>(k)]).norm());
  }
  std::printf("[ IMUREFINE] gravity %.3f -> %.3f deg, |b_a err| %.4f -> %.4f m/s^2, |b_g err| %.5f -> %.5f rad/s, "
              "max position error %.4f -> %.4f m, max velocity error %.4f m/s, |g| %.4f\n",
              gravity_before_deg, gravity_after_deg, b_a_before, b_a_after, b_g_before, b_g_after, pose_before,
              pose_after, velocity_after, refined.g_w.norm());
  // The inertial-only estimate absorbs the 1.5 cm pose errors; the joint BA removes them.
  EXPECT_LT(gravity_after_deg, 0.5 * gravity_before_deg);
  EXPECT_LT(b_a_after, 0.5 * b_a_before);
  EXPECT_LT(gravity_after_deg, 0.1);  // noise-free readings give 0.04 deg
  EXPECT_LT(b_a_after, 0.02);  // noise-free readings give 0.003
  EXPECT_LT(b_g_after, 1e-3);
  EXPECT_LT(pose_after, 0.5 * pose_before);
  EXPECT_LT(velocity_after, 0.03);
  EXPECT_NEAR(refined.g_w.norm(), 9.81, 1e-9);  // the magnitude is kept
}

/// Accelerometer bias of the newest keyframe after a visual-inertial window BA whose oldest
/// keyframe is held (pose, velocity and bias) with b_a off by `held_offset`, its bias known to
/// `held_sigma_m_s2` (LocalBaProblem::held_acc_bias_sigma_m_s2); true poses and gravity, IMU readings
/// with the true bias and the simulator's noise, points seen with 1 px noise and depth.
Vec3 windowAccBias(const imu::ImuBias& true_bias, const Vec3& held_offset, double held_sigma_m_s2) {
  std::mt19937 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  const ProjectionModel model = testModel();
  const imu::test::AnalyticTrajectory trajectory;
  imu::ImuNoise noise;
  noise.gyro_density = 1e-3;
  noise.acc_density = 1e-2;
  noise.gyro_walk_density = 1e-5;
  noise.acc_walk_density = 2e-4;
  constexpr int kNumKeyFrames = 11;
  constexpr double kSpacing_s = 0.25;
  LocalBaProblem problem;
  problem.model = model;
  problem.g_w = imu::gravityWorld();
  problem.held_acc_bias_sigma_m_s2 = held_sigma_m_s2;
  std::vector<SE3> T_true;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    const double t = 0.5 + kSpacing_s * k;
    const imu::NavState s = trajectory.state(t);
    T_true.emplace_back(s.R_w_b, s.p_w_b);
    BaKeyFrame kf;
    kf.id = k;
    kf.T_w_b = T_true.back();
    kf.v_w_b = s.v_w_b;
    kf.bias = true_bias;
    if (k == 0) {
      kf.fixed = true;  // held: pose, velocity and bias
      kf.bias.b_a += held_offset;
    }
    problem.keyframes.push_back(kf);
    if (k > 0) {
      auto pim = std::make_shared<imu::Preintegrated>(problem.keyframes[0].bias, noise);
      pim->integrate(trajectory.samples(t - kSpacing_s, t, 200.0, true_bias, &noise, &rng));
      problem.inertial.push_back(BaInertialLink{k - 1, k, pim});
    }
  }
  addObservedPoints(problem, T_true, model, rng, normal);
  return localBundleAdjust(problem).keyframes.back().bias.b_a;
}

// A keyframe held at a wrong accelerometer bias pins the window's biases to it through the random
// walk (Eq. 58: 2e-4 m/s^2/sqrt(s) over 2.5 s is 3e-4 m/s^2); held at a bias known to 0.05 m/s^2, the
// window's own visual-inertial evidence moves them to the truth.
TEST(ImuRefinement, HeldBiasSigmaLetsTheWindowCorrectAnUncertainBias) {
  const imu::ImuBias true_bias{Vec3(0.002, -0.003, 0.0015), Vec3(0.04, -0.03, 0.05)};
  const Vec3 offset(0.06, -0.05, 0.04);  // 0.09 m/s^2: an early initialisation's error
  const Vec3 pinned = windowAccBias(true_bias, offset, 0.0);
  const Vec3 loose = windowAccBias(true_bias, offset, 0.05);
  std::printf("[ HELDBIAS ] |b_a error| held exactly %.4f, held to 0.05 m/s^2 %.4f (offset %.4f) m/s^2\n",
              (pinned - true_bias.b_a).norm(), (loose - true_bias.b_a).norm(), offset.norm());
  EXPECT_GT((pinned - true_bias.b_a).norm(), 0.8 * offset.norm());
  EXPECT_LT((loose - true_bias.b_a).norm(), 0.25 * offset.norm());
}

TEST(ImuRefinement, VisualVarianceFactorMeasuresTheCameraNoise) {
  // Keypoints 0.3 px accurate (pixels and u_r) against the 1 px model: factor 0.09. A fifth of the
  // observations gross outliers: the median moves to the inliers' 62.5th percentile (x1.4 for 3
  // dof); moving points (static weight < 0.5) with large residuals are not counted at all.
  std::mt19937 rng(23);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(-40.0, 40.0);
  const ProjectionModel model = testModel();
  LocalBaProblem problem;
  problem.model = model;
  const SE3 T_w_b(so3ExpQuat(Vec3(0.1, -0.2, 0.3)), Vec3(0.5, -0.2, 0.1));
  BaKeyFrame keyframe;
  keyframe.T_w_b = T_w_b;
  problem.keyframes.push_back(keyframe);
  auto observe = [&](int m, double pixel_sigma, double static_weight, bool outlier) {
    const Vec3 p_w = visiblePoint(rng, model, T_w_b);
    problem.points.push_back(BaPoint{m, p_w});
    const Vec3 p_c = model.T_c_x * (T_w_b.inverse() * p_w);
    BaObservation obs;
    obs.keyframe_id = 0;
    obs.point_id = m;
    obs.uv = model.camera.project(p_c) + pixel_sigma * Vec2(normal(rng), normal(rng));
    if (outlier) obs.uv += Vec2(uniform(rng), uniform(rng));
    const double u_r = model.projectRgbd(p_c).z() + pixel_sigma * normal(rng);
    obs.depth_m = model.bf_px_m / (obs.uv.x() - u_r);
    obs.static_weight = static_weight;
    problem.observations.push_back(obs);
  };
  for (int m = 0; m < 400; ++m) observe(m, 0.3, 1.0, false);
  const double clean = visualVarianceFactor(problem);
  for (int m = 400; m < 800; ++m) observe(m, 0.3, 0.1, true);  // moving: left out
  const double with_moving = visualVarianceFactor(problem);
  for (int m = 800; m < 900; ++m) observe(m, 0.3, 1.0, true);  // 20% of the static ones wrong
  const double with_outliers = visualVarianceFactor(problem);
  std::printf("[ VARFACTOR] clean %.4f, with moving points %.4f, with 20%% outliers %.4f (true 0.09)\n", clean,
              with_moving, with_outliers);
  EXPECT_NEAR(clean, 0.09, 0.02);
  EXPECT_EQ(with_moving, clean);
  EXPECT_GT(with_outliers, clean);
  EXPECT_LT(with_outliers, 1.6 * 0.09);
  EXPECT_NEAR(inertialInformationScale(problem), with_outliers, 1e-12);
}

TEST(ImuRefinement, BiasPriorFollowsTheImuNoiseAndWalk) {
  imu::ImuNoise noise;
  noise.gyro_density = 1e-3;
  noise.acc_density = 1e-2;
  noise.gyro_walk_density = 1e-5;
  noise.acc_walk_density = 2e-4;
  noise.nominal_dt_s = 0.005;
  // One 200 Hz reading: sigma^2 = density^2 / dt, plus the walk over 10 s.
  const BiasPriorInformation one = biasPriorInformation(noise, 10.0, 1.0);
  EXPECT_NEAR(1.0 / one.acc, 1e-4 / 0.005 + 4e-8 * 10.0, 1e-12);
  EXPECT_NEAR(1.0 / one.gyro, 1e-6 / 0.005 + 1e-10 * 10.0, 1e-15);
  // Far weaker than the old fixed pin on b_a (1e5): a 0.03 m/s^2 bias is not held near zero.
  EXPECT_LT(one.acc, 100.0);
  const BiasPriorInformation hundred = biasPriorInformation(noise, 10.0, 100.0);
  EXPECT_NEAR(1.0 / hundred.acc, 1e-4 / 0.005 / 100.0 + 4e-8 * 10.0, 1e-12);
  const BiasPriorInformation none = biasPriorInformation(noise, 10.0, 0.0);
  EXPECT_EQ(none.acc, 0.0);
  EXPECT_EQ(none.gyro, 0.0);
}

}  // namespace
}  // namespace ltlo::optim
