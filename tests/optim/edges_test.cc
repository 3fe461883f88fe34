// Every optim edge's analytic Jacobians against central differences through the shared helper
// (tests/common/numeric_jacobian.h), with the vertex's own plus() as the manifold perturbation.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <random>

#include "common/numeric_jacobian.h"
#include "common/analytic_trajectory.h"
#include "ltlo/core/lie.h"
#include "ltlo/optim/inertial_edges.h"
#include "ltlo/optim/pose_edges.h"
#include "ltlo/optim/reprojection_edges.h"
#include <sparse_opt/robust_kernel.h>
#include "ltlo/optim/vertices.h"

namespace ltlo::optim {
namespace {

// |analytic - numeric| relative to max(1, |numeric|) for vertex I of `edge`.
template <int I, typename Edge>
double jacobianError(Edge& edge) {
  using V = typename Edge::template VertexType<I>;
  using X = typename V::EstimateType;
  auto* vertex = static_cast<V*>(edge.vertex(I));
  const X x0 = vertex->estimate();
  edge.computeError();
  edge.linearizeOplus();
  const typename Edge::template JacobianType<I> analytic = edge.template jacobian<I>();
  const auto numeric = test::numericJacobianOnManifold<V::kDimension>(
      [&](const X& x) -> typename Edge::ErrorVector {
        vertex->setEstimate(x);
        edge.computeError();
        return edge.error();
      },
      x0, [&](const X& x, const typename V::Delta& delta) { return vertex->plus(x, delta); });
  vertex->setEstimate(x0);
  edge.computeError();
  return (analytic - numeric).norm() / std::max(1.0, numeric.norm());
}

template <typename Edge, int... I>
void expectAllJacobians(Edge& edge, double tolerance, std::integer_sequence<int, I...>) {
  const double errors[] = {jacobianError<I>(edge)...};
  for (size_t i = 0; i < sizeof...(I); ++i) EXPECT_LT(errors[i], tolerance) << "vertex " << i;
}

template <typename Edge>
void expectAllJacobians(Edge& edge, double tolerance = 1e-6) {
  expectAllJacobians(edge, tolerance, std::make_integer_sequence<int, Edge::kNumVertices>{});
}

SE3 randomPose(std::mt19937& rng, double angle_rad, double translation_m) {
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const Vec3 phi(uniform(rng), uniform(rng), uniform(rng));
  const Vec3 t(uniform(rng), uniform(rng), uniform(rng));
  return SE3(so3ExpQuat(angle_rad * phi.normalized()), translation_m * t);
}

ProjectionModel bodyModel(std::mt19937& rng) {
  ProjectionModel model;
  model.camera = PinholeCamera(520.0, 515.0, 319.5, 239.5, 640, 480);
  model.T_c_x = randomPose(rng, 0.3, 0.1);  // T_c_b
  model.bf_px_m = 520.0 * 0.08;
  return model;
}

// A world point 2..4 m in front of the camera of pose T_w_c.
Vec3 pointInFront(std::mt19937& rng, const SE3& T_w_c) {
  std::uniform_real_distribution<double> lateral(-0.8, 0.8);
  std::uniform_real_distribution<double> depth(2.0, 4.0);
  return T_w_c * Vec3(lateral(rng), lateral(rng), depth(rng));
}

TEST(OptimEdges, RgbdReprojectionBodyPoseJacobiansMatchNumeric) {
  std::mt19937 rng(1);
  for (int trial = 0; trial < 5; ++trial) {
    const ProjectionModel model = bodyModel(rng);
    VertexPose pose(0, randomPose(rng, 2.5, 3.0));
    VertexPoint point(1, pointInFront(rng, pose.estimate() * model.T_c_x.inverse()));
    EdgeRgbdReprojection<VertexPose> edge(model);
    edge.setVertex(0, &pose);
    edge.setVertex(1, &point);
    edge.setMeasurement(Vec3(300.0, 200.0, 280.0));
    expectAllJacobians(edge);
  }
}

TEST(OptimEdges, ReprojectionWithAFixedPoseFillsThePointJacobianOnly) {
  // Local BA's fixed keyframes: the pose block is skipped (never read); the point block is the
  // same as with the pose free.
  std::mt19937 rng(4);
  const ProjectionModel model = bodyModel(rng);
  VertexPose pose(0, randomPose(rng, 2.5, 3.0));
  VertexPoint point(1, pointInFront(rng, pose.estimate() * model.T_c_x.inverse()));
  const auto linearise = [&](auto& edge) {
    edge.setVertex(0, &pose);
    edge.setVertex(1, &point);
    edge.computeError();
    edge.linearizeOplus();
  };
  EdgeRgbdReprojection<VertexPose> rgbd(model);
  EdgeMonoReprojection<VertexPose> mono(model);
  linearise(rgbd);
  linearise(mono);
  const Mat3 rgbd_point_free = rgbd.jacobian<1>();
  const Eigen::Matrix<double, 2, 3> mono_point_free = mono.jacobian<1>();
  ASSERT_GT(rgbd.jacobian<0>().norm(), 0.0);
  pose.setFixed(true);
  EdgeRgbdReprojection<VertexPose> rgbd_fixed(model);
  EdgeMonoReprojection<VertexPose> mono_fixed(model);
  linearise(rgbd_fixed);
  linearise(mono_fixed);
  EXPECT_EQ(rgbd_fixed.jacobian<1>(), rgbd_point_free);
  EXPECT_EQ(mono_fixed.jacobian<1>(), mono_point_free);
  EXPECT_EQ(rgbd_fixed.jacobian<0>().norm(), 0.0);
  EXPECT_EQ(mono_fixed.jacobian<0>().norm(), 0.0);
}

TEST(OptimEdges, RgbdReprojectionCameraPoseJacobiansMatchNumeric) {
  std::mt19937 rng(2);
  ProjectionModel model = bodyModel(rng);
  model.T_c_x = SE3();
  for (int trial = 0; trial < 5; ++trial) {
    VertexCameraPose pose(0, randomPose(rng, 2.5, 3.0));
    VertexPoint point(1, pointInFront(rng, pose.estimate().inverse()));
    EdgeRgbdReprojection<VertexCameraPose> edge(model);
    edge.setVertex(0, &pose);
    edge.setVertex(1, &point);
    edge.setMeasurement(Vec3(300.0, 200.0, 280.0));
    expectAllJacobians(edge);
  }
}

TEST(OptimEdges, MonoReprojectionJacobiansMatchNumeric) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 5; ++trial) {
    const ProjectionModel model = bodyModel(rng);
    VertexPose pose(0, randomPose(rng, 2.5, 3.0));
    VertexPoint point(1, pointInFront(rng, pose.estimate() * model.T_c_x.inverse()));
    EdgeMonoReprojection<VertexPose> edge(model);
    edge.setVertex(0, &pose);
    edge.setVertex(1, &point);
    edge.setMeasurement(Vec2(300.0, 200.0));
    expectAllJacobians(edge);

    ProjectionModel camera_model = model;
    camera_model.T_c_x = SE3();
    VertexCameraPose camera_pose(2, randomPose(rng, 2.5, 3.0));
    point.setEstimate(pointInFront(rng, camera_pose.estimate().inverse()));
    EdgeMonoReprojection<VertexCameraPose> camera_edge(camera_model);
    camera_edge.setVertex(0, &camera_pose);
    camera_edge.setVertex(1, &point);
    camera_edge.setMeasurement(Vec2(300.0, 200.0));
    expectAllJacobians(camera_edge);
  }
}

TEST(OptimEdges, PoseOnlyReprojectionJacobiansMatchNumeric) {
  std::mt19937 rng(4);
  for (int trial = 0; trial < 5; ++trial) {
    const ProjectionModel model = bodyModel(rng);
    VertexPose pose(0, randomPose(rng, 2.5, 3.0));
    const Vec3 p_w = pointInFront(rng, pose.estimate() * model.T_c_x.inverse());
    EdgeRgbdReprojectionPoseOnly<VertexPose> rgbd(model, p_w);
    rgbd.setVertex(0, &pose);
    rgbd.setMeasurement(Vec3(300.0, 200.0, 280.0));
    expectAllJacobians(rgbd);
    EdgeMonoReprojectionPoseOnly<VertexPose> mono(model, p_w);
    mono.setVertex(0, &pose);
    mono.setMeasurement(Vec2(300.0, 200.0));
    expectAllJacobians(mono);
  }
}

TEST(OptimEdges, RgbdObservationMatchesProjectionOfBackProjectedPoint) {
  std::mt19937 rng(5);
  const ProjectionModel model = bodyModel(rng);
  const Vec2 uv(101.0, 377.0);
  const double depth_m = 2.7;
  const Vec3 p_c = model.camera.backProject(uv, depth_m);
  const Vec3 observation = model.rgbdObservation(uv, depth_m);
  EXPECT_LT((model.projectRgbd(p_c) - observation).norm(), 1e-9);
  EXPECT_NEAR(observation.z(), 101.0 - 41.6 / 2.7, 1e-9);
}

TEST(OptimEdges, StaticWeightScalesTheRobustCostBySquare) {
  std::mt19937 rng(6);
  const ProjectionModel model = bodyModel(rng);
  VertexPose pose(0, randomPose(rng, 1.0, 1.0));
  const Vec3 p_w = pointInFront(rng, pose.estimate() * model.T_c_x.inverse());
  EdgeRgbdReprojectionPoseOnly<VertexPose> edge(model, p_w);
  edge.setVertex(0, &pose);
  edge.setMeasurement(model.projectRgbd(edge.cameraPoint()) + Vec3(1.0, -2.0, 0.5));
  edge.setObservationInformation(0.25 * Mat3::Identity());  // sigma 2 px
  edge.setStaticWeight(0.6);
  const double unweighted = 0.25 * (1.0 + 4.0 + 0.25);
  edge.evaluateChi2();
  EXPECT_NEAR(edge.unweightedChi2(), unweighted, 1e-9);
  EXPECT_NEAR(edge.chi2(), unweighted, 1e-9);  // the kernel argument is the unweighted |r|^2
  EXPECT_NEAR(edge.robustChi2(), 0.36 * unweighted, 1e-9);
  // With Huber (delta^2 = 1, below |r|^2 = 1.3125): w^2 rho_H(|r|^2), the kink not moved by w.
  edge.setRobustKernel(std::make_unique<sparse_opt::HuberKernel>(1.0));
  EXPECT_NEAR(edge.robustChi2(), 0.36 * huberLoss(unweighted, 1.0), 1e-9);
  edge.setStaticWeight(1.0);
  EXPECT_NEAR(edge.robustChi2(), huberLoss(unweighted, 1.0), 1e-9);
}

TEST(OptimEdges, StaticWeightedCostFollowsEquation53) {
  // Huber delta 2: rho_H(s) = s below 4, 4 sqrt(s) - 4 above.
  EXPECT_NEAR(huberLoss(3.0, 2.0), 3.0, 1e-12);
  EXPECT_NEAR(huberLoss(9.0, 2.0), 8.0, 1e-12);
  // beta = 0.5, gamma = 0.8, r_sq = 9 (-> 8), c_hat = 1 (-> 1):
  // 0.25 * 0.64 * 8 + 0.25 * 0.04 * 1 = 1.28 + 0.01.
  EXPECT_NEAR(staticWeightedCost(0.5, 0.8, 9.0, 1.0, 2.0), 1.29, 1e-12);
  // A fully static observation costs rho_H(r_sq); a fully dynamic one rho_H(c_hat).
  EXPECT_NEAR(staticWeightedCost(1.0, 1.0, 9.0, 1.0, 2.0), 8.0, 1e-12);
  EXPECT_NEAR(staticWeightedCost(0.0, 0.0, 9.0, 1.0, 2.0), 1.0, 1e-12);
}

// Preintegration over [1, 1.4] s of the analytic trajectory, linearised at a non-zero bias.
std::shared_ptr<const imu::Preintegrated> analyticPreintegration(const imu::ImuBias& true_bias,
                                                                 const imu::ImuBias& linearisation_bias) {
  const imu::test::AnalyticTrajectory trajectory;
  auto pim = std::make_shared<imu::Preintegrated>(linearisation_bias, imu::ImuNoise());
  pim->integrate(trajectory.samples(1.0, 1.4, 200.0, true_bias));
  return pim;
}

TEST(OptimEdges, InertialJacobiansMatchNumeric) {
  std::mt19937 rng(7);
  const imu::test::AnalyticTrajectory trajectory;
  const imu::ImuBias true_bias{Vec3(0.01, -0.02, 0.015), Vec3(0.1, -0.05, 0.08)};
  const auto pim = analyticPreintegration(true_bias, imu::ImuBias{});
  const imu::NavState s_i = trajectory.state(1.0);
  const imu::NavState s_j = trajectory.state(1.4);
  // Perturbed states so the residual is not zero.
  VertexPose pose_i(0, SE3(s_i.R_w_b, s_i.p_w_b) * randomPose(rng, 0.05, 0.05));
  VertexVelocity v_i(1, s_i.v_w_b + Vec3(0.03, -0.02, 0.01));
  VertexGyroBias b_g(2, Vec3(0.012, -0.018, 0.01));
  VertexAccBias b_a(3, Vec3(0.09, -0.04, 0.1));
  VertexPose pose_j(4, SE3(s_j.R_w_b, s_j.p_w_b) * randomPose(rng, 0.05, 0.05));
  VertexVelocity v_j(5, s_j.v_w_b + Vec3(-0.01, 0.02, 0.03));
  EdgeInertial edge(pim);
  edge.setVertex(0, &pose_i);
  edge.setVertex(1, &v_i);
  edge.setVertex(2, &b_g);
  edge.setVertex(3, &b_a);
  edge.setVertex(4, &pose_j);
  edge.setVertex(5, &v_j);
  expectAllJacobians(edge, 1e-6);

  VertexGravityDir gravity(6, imu::gravityRotationFromDirection(Vec3(0.1, -0.2, -1.0)));
  EdgeInertialGravity gravity_edge(pim);
  gravity_edge.setVertex(0, &pose_i);
  gravity_edge.setVertex(1, &v_i);
  gravity_edge.setVertex(2, &b_g);
  gravity_edge.setVertex(3, &b_a);
  gravity_edge.setVertex(4, &pose_j);
  gravity_edge.setVertex(5, &v_j);
  gravity_edge.setVertex(6, &gravity);
  expectAllJacobians(gravity_edge, 1e-6);
}

TEST(OptimEdges, InertialResidualVanishesAtTruthAndUsesPreintegrationInformation) {
  const imu::test::AnalyticTrajectory trajectory;
  const imu::ImuBias bias{Vec3(0.01, -0.02, 0.015), Vec3(0.1, -0.05, 0.08)};
  const auto pim = analyticPreintegration(bias, bias);
  const imu::NavState s_i = trajectory.state(1.0);
  const imu::NavState s_j = trajectory.state(1.4);
  VertexPose pose_i(0, SE3(s_i.R_w_b, s_i.p_w_b));
  VertexVelocity v_i(1, s_i.v_w_b);
  VertexGyroBias b_g(2, bias.b_g);
  VertexAccBias b_a(3, bias.b_a);
  VertexPose pose_j(4, SE3(s_j.R_w_b, s_j.p_w_b));
  VertexVelocity v_j(5, s_j.v_w_b);
  EdgeInertial edge(pim);
  edge.setVertex(0, &pose_i);
  edge.setVertex(1, &v_i);
  edge.setVertex(2, &b_g);
  edge.setVertex(3, &b_a);
  edge.setVertex(4, &pose_j);
  edge.setVertex(5, &v_j);
  edge.computeError();
  // Midpoint integration at 200 Hz of the smooth trajectory: residual below 1e-5 (rad, m/s, m).
  EXPECT_LT(edge.error().cwiseAbs().maxCoeff(), 1e-5);
  EXPECT_LT((edge.information() * pim->covariance() - Mat9::Identity()).norm(), 1e-6);
}

TEST(OptimEdges, BiasWalkJacobiansAndInformation) {
  VertexGyroBias b_g_i(0, Vec3(0.01, 0.02, -0.01));
  VertexAccBias b_a_i(1, Vec3(0.1, -0.2, 0.05));
  VertexGyroBias b_g_j(2, Vec3(0.012, 0.018, -0.011));
  VertexAccBias b_a_j(3, Vec3(0.11, -0.21, 0.04));
  EdgeBiasWalk edge;
  edge.setVertex(0, &b_g_i);
  edge.setVertex(1, &b_a_i);
  edge.setVertex(2, &b_g_j);
  edge.setVertex(3, &b_a_j);
  expectAllJacobians(edge, 1e-8);
  edge.computeError();
  EXPECT_NEAR(edge.error()[0], 0.002, 1e-12);
  EXPECT_NEAR(edge.error()[5], -0.01, 1e-12);

  // lambda_imu scales Sigma^-1 (Eq. 58); Sigma_bg = sigma_w^2 dt per axis.
  imu::ImuNoise noise;
  const Mat6 information = biasWalkInformation(noise, 0.5, 4.0);
  const double sigma_g2 = noise.gyro_walk_density * noise.gyro_walk_density * 0.5;
  const double sigma_a2 = noise.acc_walk_density * noise.acc_walk_density * 0.5;
  EXPECT_NEAR(information(0, 0) * sigma_g2, 4.0, 1e-9);
  EXPECT_NEAR(information(5, 5) * sigma_a2, 4.0, 1e-9);
}

TEST(OptimEdges, PriorJacobiansMatchNumeric) {
  std::mt19937 rng(8);
  VertexPose pose(0, randomPose(rng, 2.0, 2.0));
  EdgePosePrior pose_prior;
  pose_prior.setVertex(0, &pose);
  pose_prior.setMeasurement(pose.estimate() * randomPose(rng, 0.3, 0.2));
  expectAllJacobians(pose_prior);
  // At the prior the residual is zero and a small step delta gives residual delta.
  pose_prior.setMeasurement(pose.estimate());
  Vec6 delta;
  delta << 1e-4, -2e-4, 3e-4, 2e-4, 1e-4, -1e-4;
  VertexPose stepped(1, pose.plus(pose.estimate(), delta));
  pose_prior.setVertex(0, &stepped);
  pose_prior.computeError();
  EXPECT_LT((pose_prior.error() - delta).norm(), 1e-7);

  VertexVelocity velocity(2, Vec3(1.0, 2.0, 3.0));
  EdgeVelocityPrior velocity_prior;
  velocity_prior.setVertex(0, &velocity);
  velocity_prior.setMeasurement(Vec3(0.5, 2.5, 3.0));
  expectAllJacobians(velocity_prior, 1e-8);
  velocity_prior.computeError();
  EXPECT_LT((velocity_prior.error() - Vec3(0.5, -0.5, 0.0)).norm(), 1e-12);
}

TEST(OptimEdges, StatePriorJacobiansMatchNumericAndResidualIsThePerturbation) {
  std::mt19937 rng(9);
  VertexPose pose(0, randomPose(rng, 2.0, 2.0));
  VertexVelocity velocity(1, Vec3(0.4, -0.2, 0.1));
  VertexGyroBias gyro(2, Vec3(0.002, -0.001, 0.003));
  VertexAccBias acc(3, Vec3(0.03, 0.02, -0.04));
  InertialState x0;
  x0.T_w_b = pose.estimate() * randomPose(rng, 0.3, 0.2);
  x0.v_w_b = Vec3(0.5, -0.1, 0.0);
  x0.bias.b_g = Vec3(0.001, 0.0, 0.002);
  x0.bias.b_a = Vec3(0.0, 0.01, -0.02);
  EdgeStatePrior prior;
  prior.setVertex(0, &pose);
  prior.setVertex(1, &velocity);
  prior.setVertex(2, &gyro);
  prior.setVertex(3, &acc);
  prior.setMeasurement(x0);
  expectAllJacobians(prior);
  // At x0 stepped by a small delta the residual is the delta (the marginal's coordinates).
  Vec15 delta;
  delta << 1e-4, -2e-4, 3e-4, 2e-4, 1e-4, -1e-4, 0.01, -0.02, 0.03, 1e-4, 2e-4, -3e-4, 1e-3, -2e-3, 3e-3;
  pose.setEstimate(pose.plus(x0.T_w_b, delta.head<6>()));
  velocity.setEstimate(x0.v_w_b + delta.segment<3>(6));
  gyro.setEstimate(x0.bias.b_g + delta.segment<3>(9));
  acc.setEstimate(x0.bias.b_a + delta.segment<3>(12));
  prior.computeError();
  EXPECT_LT((prior.error() - delta).norm(), 1e-7);
}

TEST(OptimEdges, RelativePoseJacobiansMatchNumeric) {
  std::mt19937 rng(9);
  for (int trial = 0; trial < 5; ++trial) {
    VertexPose pose_i(0, randomPose(rng, 2.5, 3.0));
    VertexPose pose_j(1, randomPose(rng, 2.5, 3.0));
    EdgeRelativePose edge;
    edge.setVertex(0, &pose_i);
    edge.setVertex(1, &pose_j);
    edge.setMeasurement(pose_i.estimate().inverse() * pose_j.estimate() * randomPose(rng, 0.4, 0.3));
    expectAllJacobians(edge);
  }
}

TEST(OptimEdges, GravityDirectionVertexKeepsYaw) {
  const Mat3 R_w_g = so3Exp(Vec3(0.1, -0.2, 0.7));
  VertexGravityDir gravity(0, R_w_g);
  const Mat3 updated = gravity.plus(R_w_g, Vec2(0.01, -0.02));
  EXPECT_LT((so3Log(R_w_g.transpose() * updated) - Vec3(0.01, -0.02, 0.0)).norm(), 1e-12);
}

}  // namespace
}  // namespace ltlo::optim
