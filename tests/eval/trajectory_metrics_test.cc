#include "ltlo/eval/trajectory_metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace ltlo::eval {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// A 3D trajectory (helix with turning orientation) at 10 Hz; positions come in equal pairs
// (k = 2m, 2m + 1) so that an alternating perturbation is uncorrelated with them.
io::Trajectory pairedHelix(int num_pairs) {
  io::Trajectory trajectory;
  for (int m = 0; m < num_pairs; ++m) {
    const double a = 0.3 * m;
    const Vec3 p(std::cos(a), std::sin(a), 0.1 * m);
    for (int j = 0; j < 2; ++j) {
      const int k = 2 * m + j;
      trajectory.push_back({0.1 * k, SE3(so3ExpQuat(Vec3(0.0, 0.0, 0.05 * k)), p)});
    }
  }
  return trajectory;
}

MatchedTrajectories transformed(const io::Trajectory& gt, const Sim3& S_est_gt) {
  MatchedTrajectories matched;
  matched.gt = gt;
  for (const io::StampedPose& pose : gt) {
    matched.est.push_back({pose.t_s, S_est_gt.transformPose(pose.T_w_x)});
  }
  return matched;
}

TEST(ErrorStats, HandComputed) {
  const ErrorStats stats = computeErrorStats({3.0, 1.0, 4.0, 2.0});
  EXPECT_EQ(stats.count, 4);
  EXPECT_DOUBLE_EQ(stats.mean, 2.5);
  EXPECT_DOUBLE_EQ(stats.median, 2.5);
  EXPECT_DOUBLE_EQ(stats.rmse, std::sqrt(30.0 / 4.0));
  EXPECT_DOUBLE_EQ(stats.min, 1.0);
  EXPECT_DOUBLE_EQ(stats.max, 4.0);
  EXPECT_DOUBLE_EQ(computeErrorStats({5.0, 1.0, 2.0}).median, 2.0);
  EXPECT_EQ(computeErrorStats({}).count, 0);
}

TEST(Ate, RigidlyMovedTrajectoryAlignsToZero) {
  const io::Trajectory gt = pairedHelix(20);
  const Sim3 S_est_gt(so3ExpQuat(Vec3(0.3, -1.2, 2.0)), Vec3(5.0, -2.0, 1.0), 1.0);
  const AteResult ate = computeAte(transformed(gt, S_est_gt), /*with_scale=*/false);
  EXPECT_LT(ate.error_m.rmse, 1e-9);
  EXPECT_LT(ate.error_m.max, 1e-9);
  // The alignment is the inverse of the applied transform.
  const Sim3 product = ate.S_gt_est * S_est_gt;
  EXPECT_LT(product.quaternion().angularDistance(Quat::Identity()), 1e-9);
  EXPECT_LT(product.translation().norm(), 1e-9);
  EXPECT_NEAR(ate.S_gt_est.scale(), 1.0, 1e-12);
}

TEST(Ate, AlternatingPerturbationGivesItsRmse) {
  const double d_m = 0.05;
  const io::Trajectory gt = pairedHelix(20);
  const Sim3 S_est_gt(so3ExpQuat(Vec3(-0.4, 0.2, 0.9)), Vec3(1.0, 2.0, 3.0), 1.0);
  MatchedTrajectories matched = transformed(gt, S_est_gt);
  // +d, -d alternating along the world x axis of the ground truth, then moved like the rest.
  for (size_t k = 0; k < gt.size(); ++k) {
    const Vec3 p_gt = gt[k].T_w_x.translation() + Vec3((k % 2 == 0 ? d_m : -d_m), 0.0, 0.0);
    matched.est[k].T_w_x.translation() = S_est_gt * p_gt;
  }
  const AteResult ate = computeAte(matched, false);
  EXPECT_NEAR(ate.error_m.rmse, d_m, 1e-9);
  EXPECT_NEAR(ate.error_m.mean, d_m, 1e-9);
  EXPECT_NEAR(ate.error_m.max, d_m, 1e-9);
}

TEST(Ate, Sim3RecoversKnownScale) {
  const io::Trajectory gt = pairedHelix(15);
  const double scale_est_gt = 0.4;  // the estimate is 0.4 times too small (monocular-like)
  const Sim3 S_est_gt(so3ExpQuat(Vec3(0.1, 0.2, -0.3)), Vec3(-1.0, 0.5, 2.0), scale_est_gt);
  const MatchedTrajectories matched = transformed(gt, S_est_gt);
  const AteResult sim3 = computeAte(matched, /*with_scale=*/true);
  EXPECT_NEAR(sim3.S_gt_est.scale(), 1.0 / scale_est_gt, 1e-9);
  EXPECT_LT(sim3.error_m.rmse, 1e-9);
  const AteResult se3 = computeAte(matched, /*with_scale=*/false);
  EXPECT_GT(se3.error_m.rmse, 0.1);  // a rigid alignment cannot absorb the scale
}

TEST(Rpe, ConstantTranslationDriftPerFrame) {
  // Ground truth moves 0.1 m per frame along x; the estimate adds 0.01 m per frame along y.
  const double dt_s = 0.05;
  MatchedTrajectories matched;
  for (int k = 0; k < 30; ++k) {
    const Quat q = so3ExpQuat(Vec3(0.0, 0.0, 0.02 * k));
    matched.gt.push_back({k * dt_s, SE3(q, Vec3(0.1 * k, 0.0, 0.0))});
    matched.est.push_back({k * dt_s, SE3(q, Vec3(0.1 * k, 0.01 * k, 0.0))});
  }
  const RpeResult rpe = computeRpe(matched);
  EXPECT_EQ(rpe.trans_m_frame.count, 29);
  EXPECT_NEAR(rpe.trans_m_frame.rmse, 0.01, 1e-12);
  EXPECT_NEAR(rpe.trans_m_frame.max, 0.01, 1e-12);
  EXPECT_NEAR(rpe.trans_m_s.rmse, 0.01 / dt_s, 1e-9);
  EXPECT_NEAR(rpe.rot_deg_frame.rmse, 0.0, 1e-9);
  // A rigid motion of the whole estimate changes nothing; a Sim3 scales the translation error.
  const Sim3 rigid(so3ExpQuat(Vec3(1, 2, 3)), Vec3(4, 5, 6), 1.0);
  EXPECT_NEAR(computeRpe(matched, rigid).trans_m_frame.rmse, 0.01, 1e-12);
  EXPECT_NEAR(computeRpe(matched, Sim3(Quat::Identity(), Vec3::Zero(), 2.0)).trans_m_frame.rmse,
              std::hypot(0.1, 0.02), 1e-12);  // est relative motion (0.2, 0.02) vs (0.1, 0)
}

TEST(Rpe, ConstantRotationDriftPerFrame) {
  const double dt_s = 0.1;
  const double drift_deg = 0.5;
  MatchedTrajectories matched;
  for (int k = 0; k < 20; ++k) {
    matched.gt.push_back({k * dt_s, SE3(so3ExpQuat(Vec3(0.0, 0.0, 0.1 * k)), Vec3::Zero())});
    matched.est.push_back(
        {k * dt_s,
         SE3(so3ExpQuat(Vec3(0.0, 0.0, 0.1 * k + drift_deg * kDegToRad * k)), Vec3::Zero())});
  }
  const RpeResult rpe = computeRpe(matched);
  EXPECT_NEAR(rpe.rot_deg_frame.rmse, drift_deg, 1e-9);
  EXPECT_NEAR(rpe.rot_deg_s.rmse, drift_deg / dt_s, 1e-8);
  EXPECT_NEAR(rpe.trans_m_frame.rmse, 0.0, 1e-12);
}

TEST(Association, JitteredTimestampsPairWithinTolerance) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> jitter_s(-0.008, 0.008);
  io::Trajectory gt;
  io::Trajectory est;
  for (int k = 0; k < 100; ++k) gt.push_back({1.0 + 0.05 * k, SE3()});
  for (int k = 0; k < 100; ++k) {
    if (k % 10 == 3) continue;  // dropped frames
    est.push_back({1.0 + 0.05 * k + jitter_s(rng), SE3()});
  }
  est.push_back({100.0, SE3()});  // no ground truth near it
  const MatchedTrajectories matched = associateTrajectories(gt, est, 0.02);
  ASSERT_EQ(matched.gt.size(), 90u);
  for (size_t k = 0; k < matched.gt.size(); ++k) {
    EXPECT_LE(std::abs(matched.gt[k].t_s - matched.est[k].t_s), 0.008 + 1e-12);
    if (k > 0) {
      EXPECT_GT(matched.gt[k].t_s, matched.gt[k - 1].t_s);
    }
  }
  EXPECT_LT(associateTrajectories(gt, est, 0.001).gt.size(), 90u);  // tighter: fewer pairs
}

}  // namespace
}  // namespace ltlo::eval
