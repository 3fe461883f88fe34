// The pose-gravity check (Tracking.StartMotionCheck, issue 32) on an analytic trajectory whose
// IMU deltas are exact: poses that follow the camera give gravity to rounding, also with 1 mm of
// tracking noise within its bound; poses that follow a mover at a constant velocity are
// indistinguishable (the documented blind spot); poses whose velocity changes by 0.5 m/s without
// a force (tracking changing the world it follows) fail in the window across the change.
#include "ltlo/imu/pose_gravity_check.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include "ltlo/core/lie.h"

namespace ltlo::imu {
namespace {

constexpr double kFps = 30.0;
constexpr double kSeconds = 3.0;

// Gravity of a world whose z is tilted off the vertical, so the check cannot assume its direction.
Vec3 gravityW() { return so3Exp(Vec3(0.2, -0.1, 0.0)) * Vec3(0.0, 0.0, -9.81); }

Vec3 position(double t) { return Vec3(0.5 * t + 0.2 * std::sin(1.3 * t), 0.3 * std::sin(0.7 * t), 0.05 * std::sin(2.0 * t)); }
Vec3 velocity(double t) {
  return Vec3(0.5 + 0.26 * std::cos(1.3 * t), 0.21 * std::cos(0.7 * t), 0.1 * std::cos(2.0 * t));
}
Mat3 rotation(double t) { return so3Exp(Vec3(0.1 * std::sin(t), 0.2 * std::sin(0.5 * t), 0.4 * t)); }

struct CheckedWindows {
  std::vector<PoseGravityVerdict> verdicts;
  std::vector<double> times;
};

/// Feeds frames at kFps with the exact deltas of the true motion and the poses `tracked(t)` gives.
CheckedWindows feed(PoseGravityCheck& check, const std::function<Vec3(double)>& tracked, double sigma_m = 0.0) {
  CheckedWindows run;
  const Vec3 g = gravityW();
  for (int k = 0; k <= static_cast<int>(kSeconds * kFps); ++k) {
    const double t = k / kFps, t0 = (k - 1) / kFps, dt = 1.0 / kFps;
    // The preintegrated deltas by their definition from the states at both ends.
    const Mat3 R0 = rotation(t0);
    const Mat3 dR = R0.transpose() * rotation(t);
    const Vec3 dV = R0.transpose() * (velocity(t) - velocity(t0) - g * dt);
    const Vec3 dP = R0.transpose() * (position(t) - position(t0) - velocity(t0) * dt - 0.5 * g * dt * dt);
    const PoseGravityVerdict verdict = check.add(t, SE3(rotation(t), tracked(t)), sigma_m, dR, dV, dP, dt);
    if (verdict.checked) {
      run.verdicts.push_back(verdict);
      run.times.push_back(t);
    }
  }
  return run;
}

TEST(PoseGravityCheck, PosesThatFollowTheCameraGiveGravity) {
  PoseGravityCheck check({0.1, 3.0});
  const CheckedWindows run = feed(check, position);
  ASSERT_GE(run.verdicts.size(), 25u);
  for (const PoseGravityVerdict& verdict : run.verdicts) {
    EXPECT_TRUE(verdict.consistent);
    EXPECT_LT(verdict.error_m_s2, 1e-9);
    EXPECT_LT((verdict.g_w - gravityW()).norm(), 1e-9);
  }
}

TEST(PoseGravityCheck, PosesThatFollowAMoverAtAConstantVelocityCannotBeTold) {
  PoseGravityCheck check({0.1, 3.0});
  const CheckedWindows run = feed(check, [](double t) { return Vec3(position(t) - Vec3(0.4, 0.1, 0.0) * t); });
  for (const PoseGravityVerdict& verdict : run.verdicts) EXPECT_LT(verdict.error_m_s2, 1e-9);
}

TEST(PoseGravityCheck, TrackingNoiseOfOneMillimetreStaysWithinTheBound) {
  PoseGravityCheck check({0.1, 3.0});
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.001);
  const CheckedWindows run = feed(check, [&](double t) { return Vec3(position(t) + Vec3(noise(rng), noise(rng), noise(rng))); });
  double largest = 0.0;
  for (const PoseGravityVerdict& verdict : run.verdicts) {
    EXPECT_TRUE(verdict.consistent);
    largest = std::max(largest, verdict.error_m_s2);
  }
  EXPECT_GT(largest, 0.05);  // the noise is seen ...
  EXPECT_LT(largest, 1.5);   // ... and stays well inside 3 m/s^2 (about 0.25 m/s^2 per axis)
  EXPECT_EQ(check.state().max_error_m_s2, largest);
}

TEST(PoseGravityCheck, AVelocityChangeWithoutAForceFailsTheWindowAcrossIt) {
  // Tracking follows a box moving with the camera until 1 s (the poses miss 0.5 m/s of the motion),
  // then the room: the poses' velocity jumps by 0.5 m/s, which no accelerometer reading explains.
  constexpr double kSwitchS = 1.0;
  const Vec3 missed(0.45, 0.2, 0.0);
  PoseGravityCheck check({0.1, 3.0});
  const CheckedWindows run = feed(check, [&](double t) { return Vec3(position(t) - missed * std::min(t, kSwitchS)); });
  std::size_t first_failure = run.verdicts.size();
  for (std::size_t i = 0; i < run.verdicts.size(); ++i) {
    if (!run.verdicts[i].consistent) {
      first_failure = i;
      break;
    }
  }
  ASSERT_LT(first_failure, run.verdicts.size());
  EXPECT_GT(run.times[first_failure], kSwitchS);
  EXPECT_LE(run.times[first_failure], kSwitchS + 0.2 + 1.0 / kFps);  // the first window that spans the change
  EXPECT_GT(run.verdicts[first_failure].error_m_s2, 3.0);
  for (std::size_t i = 0; i < first_failure; ++i) EXPECT_LT(run.verdicts[i].error_m_s2, 1e-9);
}

TEST(PoseGravityCheck, UncertainPosesWidenTheBound) {
  // The same change with poses of 2 cm sigma (a frame tracked on a few dozen points): the bound is
  // 5 sigma of the window's estimate, sqrt(6) * 0.02 m / (0.1 s)^2 * 5 = 24 m/s^2, and the change passes.
  const Vec3 missed(0.45, 0.2, 0.0);
  PoseGravityCheck check({0.1, 3.0});
  const CheckedWindows run =
      feed(check, [&](double t) { return Vec3(position(t) - missed * std::min(t, 1.0)); }, 0.02);
  ASSERT_FALSE(run.verdicts.empty());
  for (const PoseGravityVerdict& verdict : run.verdicts) {
    EXPECT_TRUE(verdict.consistent);
    EXPECT_NEAR(verdict.bound_m_s2, 5.0 * std::sqrt(6.0) * 0.02 / (0.1 * 0.1), 0.5);
  }
}

TEST(PoseGravityCheck, AResetStartsAFreshChain) {
  PoseGravityCheck check({0.1, 3.0});
  feed(check, position);
  EXPECT_FALSE(check.empty());
  check.reset();
  EXPECT_TRUE(check.empty());
  EXPECT_EQ(check.state().windows, 0);
  // Three nodes are needed again before the first verdict: 0.2 s of frames at 30 Hz.
  const Vec3 g = gravityW();
  int verdicts = 0;
  for (int k = 0; k <= 6; ++k) {
    const double t = 10.0 + k / kFps;
    const Mat3 R0 = rotation(t - 1.0 / kFps);
    const double dt = 1.0 / kFps;
    const Vec3 dV = R0.transpose() * (velocity(t) - velocity(t - dt) - g * dt);
    const Vec3 dP = R0.transpose() * (position(t) - position(t - dt) - velocity(t - dt) * dt - 0.5 * g * dt * dt);
    verdicts += check.add(t, SE3(rotation(t), position(t)), 0.0, R0.transpose() * rotation(t), dV, dP, dt).checked;
  }
  EXPECT_EQ(verdicts, 1);
}

}  // namespace
}  // namespace ltlo::imu
