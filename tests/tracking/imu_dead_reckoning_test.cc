// The IMU's dead reckoning before the first map (Tracking.PreMapImuPose, issue 32) on exact readings
// of a body that rests tilted for 1 s and then drives off turning: the pose relative to the first
// frame against the truth, with the gyro and accelerometer biases the rest has to absorb.
#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/tracking/imu_dead_reckoning.h"

namespace ltlo::tracking {
namespace {

constexpr double kImuRate_hz = 200.0;
constexpr double kFramePeriod_s = 0.04;  // 8 IMU samples per frame
constexpr double kRest_s = 1.0;
const Vec3 kGravity(0.0, 0.0, -9.81);

/// Rests at p0 with a tilt until kRest_s, then accelerates along its heading, s = c tau^3, and
/// turns about the vertical, yaw = y0 + w tau^3 (tau = t - kRest_s): smooth, starting from rest.
struct RestThenDrive {
  double distance_coefficient = 0.3;  ///< c, m/s^3
  double yaw_coefficient = 0.2;       ///< w, rad/s^3
  Mat3 R_tilt = so3Exp(Vec3(0.1, -0.05, 0.0));
  Vec3 p0 = Vec3(1.0, 2.0, 0.5);
  Vec3 heading = Vec3(0.8, 0.6, 0.0);

  static double tau(double t) { return std::max(0.0, t - kRest_s); }
  Mat3 rotation(double t) const {
    const double yaw = 0.3 + yaw_coefficient * std::pow(tau(t), 3);
    return so3Exp(Vec3(0.0, 0.0, yaw)) * R_tilt;
  }
  Vec3 position(double t) const { return p0 + heading * distance_coefficient * std::pow(tau(t), 3); }
  Vec3 acceleration(double t) const { return heading * distance_coefficient * 6.0 * tau(t); }
  Vec3 yawRate(double t) const { return Vec3(0.0, 0.0, 3.0 * yaw_coefficient * tau(t) * tau(t)); }

  ImuSample sample(double t, const imu::ImuBias& bias) const {
    ImuSample s;
    s.t_s = t;
    s.gyro_rad_s = rotation(t).transpose() * yawRate(t) + bias.b_g;
    s.acc_m_s2 = rotation(t).transpose() * (acceleration(t) - kGravity) + bias.b_a;
    return s;
  }
  SE3 T_w_b(double t) const { return SE3(rotation(t), position(t)); }
};

struct Reckoned {
  SE3 T_b0_b;       ///< estimated
  SE3 T_b0_b_true;  ///< truth
  ImuDeadReckoning reckoning;
};

double positionError_m(const Reckoned& r) { return (r.T_b0_b.translation() - r.T_b0_b_true.translation()).norm(); }

/// Dead-reckons frames 0 .. t_end; the frames up to rest_until_s are called rest (every frame
/// moving without one). `replay_s` as ImuDeadReckoning's.
Reckoned reckon(const RestThenDrive& body, const imu::ImuBias& bias, double t_end,
                std::optional<double> rest_until_s, double replay_s = 0.6) {
  Reckoned out{SE3(), SE3(), ImuDeadReckoning(0.0, replay_s)};
  const int frames = static_cast<int>(std::lround(t_end / kFramePeriod_s));
  for (int k = 1; k <= frames; ++k) {
    const double t0 = (k - 1) * kFramePeriod_s;
    const double t1 = k * kFramePeriod_s;
    std::vector<ImuSample> samples;
    for (int i = static_cast<int>(std::lround(t0 * kImuRate_hz)); i <= std::lround(t1 * kImuRate_hz); ++i) {
      samples.push_back(body.sample(i / kImuRate_hz, bias));
    }
    imu::Preintegrated pim{imu::ImuBias(), imu::ImuNoise()};
    pim.integrate(samples);
    out.reckoning.propagate(t1, &pim, rest_until_s && t1 <= *rest_until_s + 1e-9);
  }
  out.T_b0_b = out.reckoning.T_w_b();
  out.T_b0_b_true = body.T_w_b(0.0).inverse() * body.T_w_b(frames * kFramePeriod_s);
  return out;
}

double rotationErrorRad(const SE3& a, const SE3& b) {
  return so3Log(a.rotationMatrix().transpose() * b.rotationMatrix()).norm();
}

imu::ImuBias sensorBias() {
  imu::ImuBias bias;
  bias.b_g = Vec3(0.002, -0.003, 0.001);
  bias.b_a = Vec3(0.05, -0.03, 0.08);
  return bias;
}

TEST(ImuDeadReckoning, TheFirstFrameIsTheWorldAndRestHoldsThePose) {
  RestThenDrive body;
  const Reckoned held = reckon(body, sensorBias(), kRest_s, kRest_s);
  EXPECT_LT(held.T_b0_b.translation().norm(), 1e-12);
  EXPECT_LT(rotationErrorRad(held.T_b0_b, SE3()), 1e-12);
  EXPECT_LT(held.reckoning.v_w_b().norm(), 1e-12);
  // Gravity from the rest's mean specific force (the accelerometer bias is in it, 0.1 m/s^2 of 9.81).
  ASSERT_TRUE(held.reckoning.g_w().has_value());
  const Vec3 g_b0 = body.rotation(0.0).transpose() * kGravity;
  EXPECT_LT((*held.reckoning.g_w() - g_b0).norm(), sensorBias().b_a.norm() + 1e-9);
  EXPECT_LT((held.reckoning.gyroBias() - sensorBias().b_g).norm(), 1e-12);
}

TEST(ImuDeadReckoning, AfterARestThePositionIsIntegratedWithTheRestsGravity) {
  // Straight ahead without turning: the tilt stays the rest's, so the accelerometer bias taken into
  // gravity cancels exactly; what is left is the integration's discretisation.
  RestThenDrive straight;
  straight.yaw_coefficient = 0.0;
  const double t_end = kRest_s + 1.6;
  const Reckoned on = reckon(straight, sensorBias(), t_end, kRest_s);
  const double travelled_m = on.T_b0_b_true.translation().norm();
  EXPECT_GT(travelled_m, 1.0);
  EXPECT_LT(positionError_m(on), 1e-3) << "travelled " << travelled_m;
  EXPECT_LT(rotationErrorRad(on.T_b0_b, on.T_b0_b_true), 1e-5);
  EXPECT_TRUE(on.reckoning.positionIntegrated());

  // Turning by 0.8 rad: the accelerometer bias rotates away from what gravity absorbed, by at most
  // |b_a| x the turned angle, integrated twice: |b_a| w tau^5 / 20 = 8.2 mm after 1.6 s.
  RestThenDrive turning;
  const Reckoned turned = reckon(turning, sensorBias(), t_end, kRest_s);
  const double bound_m = sensorBias().b_a.norm() * turning.yaw_coefficient * std::pow(1.6, 5) / 20.0;
  EXPECT_LT(positionError_m(turned), bound_m);
  EXPECT_LT(rotationErrorRad(turned.T_b0_b, turned.T_b0_b_true), 1e-4);
}

TEST(ImuDeadReckoning, AStartOfMotionSeenLateIsIntegratedFromTheLastTrustedRest) {
  // The zero-velocity test calls the first 0.2 s of motion rest (the rest's mean readings then hold
  // the start's acceleration, and the body is at 0.036 m/s when it says moving). Going
  // back 0.6 s to a rest frame before the motion recovers the straight drive to the
  // discretisation; without going back (replay 0) gravity and velocity are off.
  RestThenDrive straight;
  straight.yaw_coefficient = 0.0;
  const double t_end = kRest_s + 1.6;
  const Reckoned replayed = reckon(straight, sensorBias(), t_end, kRest_s + 0.2, 0.6);
  const Reckoned late = reckon(straight, sensorBias(), t_end, kRest_s + 0.2, 0.0);
  EXPECT_LT(positionError_m(replayed), 1e-3);
  EXPECT_GT(positionError_m(late), 0.05);
}

TEST(ImuDeadReckoning, WithoutARestOnlyTheOrientationIsKept) {
  // Every frame moving (the test never says rest): no gravity, the position held at the first
  // frame's, the orientation from the gyroscope with its bias uncorrected.
  RestThenDrive body;
  const double t_end = kRest_s + 1.6;
  const Reckoned off = reckon(body, sensorBias(), t_end, std::nullopt);
  EXPECT_FALSE(off.reckoning.positionIntegrated());
  EXPECT_FALSE(off.reckoning.g_w().has_value());
  EXPECT_LT(off.T_b0_b.translation().norm(), 1e-12);
  EXPECT_LT(rotationErrorRad(off.T_b0_b, off.T_b0_b_true), sensorBias().b_g.norm() * t_end + 1e-4);
  EXPECT_GT(rotationErrorRad(off.T_b0_b, off.T_b0_b_true), 0.5 * sensorBias().b_g.norm() * t_end);
}

TEST(ImuDeadReckoning, AFrameWithoutImuDataHoldsThePose) {
  ImuDeadReckoning reckoning(0.0, 0.6);
  reckoning.propagate(0.04, nullptr, false);
  EXPECT_LT(reckoning.T_w_b().translation().norm(), 1e-12);
  EXPECT_LT(rotationErrorRad(reckoning.T_w_b(), SE3()), 1e-12);
}

}  // namespace
}  // namespace ltlo::tracking
