// The online camera-IMU time offset (src/mapping/time_offset_estimator.h) and the exact boundary
// move of the preintegration it relies on (imu::Preintegrated::moveBoundary), on the analytic
// trajectory of the preintegration tests: exact rotations stand in for the BA's keyframe poses, the
// gyroscope stamps its readings `offset` late (t_imu = t_cam + offset).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "../../src/mapping/time_offset_estimator.h"
#include "common/analytic_trajectory.h"
#include "ltlo/core/imu_sample.h"
#include "ltlo/core/lie.h"
#include "ltlo/imu/preintegration.h"

namespace ltlo::mapping {
namespace {

using imu::test::AnalyticTrajectory;

constexpr double kRateHz = 200.0;

imu::ImuNoise testNoise() {
  imu::ImuNoise noise;
  return noise;
}

// The IMU's stream: the reading of true instant t is stamped t + offset, with the given bias.
ImuSamples imuStream(const AnalyticTrajectory& trajectory, double offset_s, const imu::ImuBias& bias, double t_end_s,
                     std::mt19937* rng = nullptr, double gyro_noise_rad_s = 0.0) {
  ImuSamples samples;
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int k = 0; k / kRateHz <= t_end_s + 0.2; ++k) {
    const double stamp = k / kRateHz;
    ImuSample s = trajectory.sample(stamp - offset_s, bias);
    s.t_s = stamp;
    if (rng != nullptr) s.gyro_rad_s += gyro_noise_rad_s * Vec3(normal(*rng), normal(*rng), normal(*rng));
    samples.push_back(s);
  }
  return samples;
}

imu::Preintegrated preintegrate(const ImuSamples& stream, double t_begin_s, double t_end_s, double shift_s,
                                const imu::ImuBias& bias = imu::ImuBias()) {
  imu::Preintegrated pim(bias, testNoise());
  pim.integrate(imuSamplesBetween(stream, t_begin_s + shift_s, t_end_s + shift_s));
  pim.setShifts(shift_s, shift_s);
  return pim;
}

TEST(PreintegrationBoundary, MovingTheBoundaryHandsTheStepsOverExactly) {
  const AnalyticTrajectory trajectory;
  const ImuSamples stream = imuStream(trajectory, 0.0, imu::ImuBias(), 2.0);
  for (const double move_s : {0.0137, -0.0212, 0.005}) {
    imu::Preintegrated earlier = preintegrate(stream, 0.3, 0.6, 0.0);
    imu::Preintegrated later = preintegrate(stream, 0.6, 0.95, 0.0);
    imu::Preintegrated::moveBoundary(earlier, later, move_s);
    EXPECT_DOUBLE_EQ(earlier.shiftEnd_s(), move_s);
    EXPECT_DOUBLE_EQ(later.shiftBegin_s(), move_s);
    EXPECT_DOUBLE_EQ(earlier.shiftBegin_s(), 0.0);
    EXPECT_NEAR(earlier.dt_s(), 0.3 + move_s, 1e-12);
    EXPECT_NEAR(later.dt_s(), 0.35 - move_s, 1e-12);
    // Against cutting the stream at the moved boundary: a step cut in two keeps its mean reading
    // on both sides, where the cut interpolates the sample: a difference of a fraction of one
    // 5 ms step's change in rate (measured 1.1e-6 rad, 4e-6 m/s, 1e-8 m).
    const imu::Preintegrated earlier_cut = preintegrate(stream, 0.3, 0.6 + move_s, 0.0);
    const imu::Preintegrated later_cut = preintegrate(stream, 0.6 + move_s, 0.95, 0.0);
    EXPECT_LT(so3Log(earlier.deltaR().transpose() * earlier_cut.deltaR()).norm(), 3e-6) << move_s;
    EXPECT_LT(so3Log(later.deltaR().transpose() * later_cut.deltaR()).norm(), 3e-6) << move_s;
    EXPECT_LT((earlier.deltaV() - earlier_cut.deltaV()).norm(), 2e-5) << move_s;
    EXPECT_LT((later.deltaV() - later_cut.deltaV()).norm(), 2e-5) << move_s;
    EXPECT_LT((earlier.deltaP() - earlier_cut.deltaP()).norm(), 1e-6) << move_s;
    // Nothing is lost or counted twice: the two together are the union they were before the move
    // up to the step cut in two, which integrates as two midpoint steps of the same readings
    // (second order in the step: measured 5e-9 m/s and 2e-8 m; the rotation to 1e-12).
    const imu::Preintegrated joined = imu::Preintegrated::merged(earlier, later);
    const imu::Preintegrated whole =
        imu::Preintegrated::merged(preintegrate(stream, 0.3, 0.6, 0.0), preintegrate(stream, 0.6, 0.95, 0.0));
    EXPECT_NEAR(joined.dt_s(), whole.dt_s(), 1e-12);
    EXPECT_LT(so3Log(joined.deltaR().transpose() * whole.deltaR()).norm(), 1e-12);
    EXPECT_LT((joined.deltaV() - whole.deltaV()).norm(), 5e-8);
    EXPECT_LT((joined.deltaP() - whole.deltaP()).norm(), 2e-7);
  }
}

// Links between keyframes every `interval_s` from 0.5 s, cut with `shift_s`, with exact rotations.
std::vector<TimeOffsetLink> linksOf(const AnalyticTrajectory& trajectory, const ImuSamples& stream, double interval_s,
                                    int count, double shift_s) {
  std::vector<TimeOffsetLink> links;
  for (int k = 0; k < count; ++k) {
    const double t0 = 0.5 + k * interval_s, t1 = t0 + interval_s;
    links.push_back(TimeOffsetLink{trajectory.rotation(t0), trajectory.rotation(t1),
                                   preintegrate(stream, t0, t1, shift_s)});
  }
  return links;
}

TEST(TimeOffsetEstimator, RecoversTheOffsetAndTheGyroBiasFromKeyframeRotations) {
  const AnalyticTrajectory trajectory;
  imu::ImuBias bias;
  bias.b_g = Vec3(0.004, -0.003, 0.002);
  for (const double offset_s : {0.02, 0.03, -0.02, 0.0}) {
    std::mt19937 rng(3);
    // Gyro white noise of a consumer IMU at 200 Hz (1.7e-4 rad/s/sqrt(Hz) -> 2.4e-3 rad/s per sample).
    const ImuSamples stream = imuStream(trajectory, offset_s, bias, 14.0, &rng, 2.4e-3);
    // Cut as tracking does before any estimate (shift 0): the estimate is the whole offset.
    const std::vector<TimeOffsetLink> links = linksOf(trajectory, stream, 0.3, 40, 0.0);
    TimeOffsetOptions options;
    const std::optional<TimeOffsetEstimate> estimate = estimateTimeOffset(links, 0.0, Vec3::Zero(), options);
    ASSERT_TRUE(estimate.has_value());
    EXPECT_NEAR(estimate->shift_s, offset_s, 5e-4) << offset_s;
    EXPECT_LT(estimate->sigma_s, 1e-3) << offset_s;
    EXPECT_LT((estimate->gyro_bias - bias.b_g).norm(), 3e-4) << offset_s;
    // Cut again at the estimate: the links now agree with it (the first-order model is not the limit).
    const std::vector<TimeOffsetLink> recut = linksOf(trajectory, stream, 0.3, 40, estimate->shift_s);
    const std::optional<TimeOffsetEstimate> again = estimateTimeOffset(recut, estimate->shift_s, estimate->gyro_bias, options);
    ASSERT_TRUE(again.has_value());
    EXPECT_NEAR(again->shift_s, offset_s, 3e-4) << offset_s;
  }
}

TEST(TimeOffsetEstimator, AConstantTurnLeavesThePriorAndSaysSo) {
  // A constant rate about a fixed axis: a shifted interval gives the same rotation, nothing tells
  // the shift, and the marginal sigma stays the prior's.
  imu::ImuNoise noise;
  std::vector<TimeOffsetLink> links;
  const Vec3 w(0.0, 0.0, 0.4);
  for (int k = 0; k < 30; ++k) {
    const double t0 = 0.3 * k, t1 = t0 + 0.3;
    imu::Preintegrated pim(imu::ImuBias(), noise);
    ImuSamples samples;
    for (int j = 0; j <= 60; ++j) samples.push_back(ImuSample{t0 + j * 0.005, w, Vec3(0.0, 0.0, 9.81)});
    pim.integrate(samples);
    links.push_back(TimeOffsetLink{so3Exp(w * t0), so3Exp(w * t1), pim});
  }
  TimeOffsetOptions options;
  const std::optional<TimeOffsetEstimate> estimate = estimateTimeOffset(links, 0.0, Vec3::Zero(), options);
  ASSERT_TRUE(estimate.has_value());
  EXPECT_NEAR(estimate->sigma_s, options.prior_sigma_s, 1e-3 * options.prior_sigma_s);
  EXPECT_NEAR(estimate->shift_s, 0.0, 1e-9);
}

}  // namespace
}  // namespace ltlo::mapping
