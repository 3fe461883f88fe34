// The IMU initialisation seeded by the rest before the first map (ImuInit.FromPreMapRest, issue 32)
// on a short chain of keyframes with exact poses and IMU readings with biases and white noise: the
// map's first 0.6 s. Gravity is held at the rest's, the gyro bias's prior sits at the rest's mean
// reading, and the velocities come out of the chain.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "../../src/mapping/imu_initializer.h"
#include "common/analytic_trajectory.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/map.h"

namespace ltlo::mapping {
namespace {

constexpr int kNumKeyFrames = 4;
constexpr double kSpacing_s = 0.2;
constexpr double kStart_s = 1.0;
constexpr double kImuRate_hz = 200.0;

double angleDeg(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI; }

struct Chain {
  map::Map map;
  ImuChain chain;
  std::vector<Vec3> v_w_b_true;
};

/// kNumKeyFrames keyframes at the analytic trajectory's exact poses, linked by preintegrations of
/// readings with `bias` and the noise model's white noise (fixed seed).
std::unique_ptr<Chain> makeChain(const imu::ImuBias& bias, const imu::ImuNoise& noise) {
  auto out = std::make_unique<Chain>();
  const imu::test::AnalyticTrajectory trajectory;
  std::mt19937 rng(11);
  for (int k = 0; k < kNumKeyFrames; ++k) {
    const double t_s = kStart_s + kSpacing_s * k;
    const imu::NavState state = trajectory.state(t_s);
    map::Frame frame(t_s, PinholeCamera(262.5, 262.5, 159.5, 119.5, 320, 240), SE3(), features::OrbFeatures(), {},
                     {1.0f});
    frame.setPose_T_w_b(SE3(state.R_w_b, state.p_w_b));
    std::shared_ptr<map::KeyFrame> kf = out->map.createKeyFrame(frame);
    if (k > 0) {
      auto pim = std::make_shared<imu::Preintegrated>(imu::ImuBias(), noise);
      pim->integrate(trajectory.samples(t_s - kSpacing_s, t_s, kImuRate_hz, bias, &noise, &rng));
      kf->setPreviousKeyFrame(out->chain.keyframes.back()->id());
      out->chain.keyframes.back()->setNextKeyFrame(kf->id());
      kf->setImuFromPrevious(*pim);
      out->chain.pims.push_back(pim);
    }
    out->chain.keyframes.push_back(kf);
    out->v_w_b_true.push_back(state.v_w_b);
  }
  return out;
}

TEST(ImuInitFromPreMapRest, HoldsTheRestsGravityAndEstimatesTheVelocities) {
  const imu::ImuBias bias{Vec3(0.002, -0.003, 0.001), Vec3(0.08, -0.05, 0.04)};
  const imu::ImuNoise noise;  // the defaults: a low-cost MEMS IMU
  ImuInitOptions options;
  const Vec3 g_true = imu::gravityWorld();
  // The rest's estimate: gravity 0.2 deg off the truth (what a rest's mean reading absorbs of a
  // horizontal accelerometer bias), the gyro bias within its sigma after 1.5 s of rest.
  imu::RestEstimate rest;
  rest.g_w = so3Exp(Vec3(0.2 * M_PI / 180.0, 0.0, 0.0)) * g_true;
  rest.b_g = bias.b_g + Vec3(1e-4, -1e-4, 5e-5);
  rest.rest_s = 1.5;

  std::unique_ptr<Chain> seeded = makeChain(bias, noise);
  const std::optional<ImuInitEstimate> with_rest =
      initialiseImuOnChain(seeded->chain, options, imu::ImuBias(), &rest);
  ASSERT_TRUE(with_rest.has_value());
  // Gravity held exactly at the rest's (to the round trip through a rotation).
  EXPECT_LT(angleDeg(with_rest->g_w, rest.g_w), 1e-6);
  EXPECT_NEAR(with_rest->g_w.norm(), imu::kGravity_m_s2, 1e-9);
  // The gyro bias stays within the rest's sigma of the truth.
  EXPECT_LT((with_rest->bias.b_g - bias.b_g).norm(), 5e-4);
  // Every keyframe's velocity from the chain (written to the keyframes).
  double worst_velocity_m_s = 0.0;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    const Vec3 error = seeded->chain.keyframes[static_cast<std::size_t>(k)]->v_w_b() - seeded->v_w_b_true[static_cast<std::size_t>(k)];
    worst_velocity_m_s = std::max(worst_velocity_m_s, error.norm());
  }
  EXPECT_LT(worst_velocity_m_s, 0.02) << "worst keyframe velocity error";
  EXPECT_TRUE(with_rest->acceleration_covariance_w.allFinite());

  // The same chain without the rest, for the log: the gravity direction is the chain's own.
  std::unique_ptr<Chain> alone = makeChain(bias, noise);
  const std::optional<ImuInitEstimate> without_rest = initialiseImuOnChain(alone->chain, options, imu::ImuBias());
  ASSERT_TRUE(without_rest.has_value());
  std::printf("rest seed: gravity held %.3f deg off the truth, worst velocity %.4f m/s; the chain alone: gravity %.3f deg off\n",
              angleDeg(with_rest->g_w, g_true), worst_velocity_m_s, angleDeg(without_rest->g_w, g_true));
}


}  // namespace
}  // namespace ltlo::mapping
