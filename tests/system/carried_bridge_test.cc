// The inertial bridge of IMU-carried stretches (system/carried_bridge.h):
//   - a turning robot dead-reckoned with a wrong accelerometer and gyroscope bias: the bridge
//     recovers the stretch to a fraction of what the blend leaves (both numbers asserted), and
//     finds the biases;
//   - with the IMU's white noise (the default ImuNoise densities) it still does;
//   - the two ends are held: an anchored frame off its true place pulls the stretch's end along
//     and leaves its start at the last tracked frame;
//   - without the margins it still beats the blend; with the IMU data of one frame missing the
//     stretch falls back to the blend;
//   - the recorder's retention keeps the IMU data of carried frames and their margins only.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "ltlo/imu/inertial_residual.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/system/carried_bridge.h"
#include "ltlo/system/carried_stretch.h"

namespace ltlo::system {
namespace {

constexpr double kFrameDt = 1.0 / 30.0;
constexpr double kImuDt = 1.0 / 200.0;
constexpr int kFrames = 121;        // 0 .. 4 s
constexpr int kFirstCarried = 30;   // 1.0 s
constexpr int kAnchored = 105;      // 3.5 s: 2.5 s carried
const Vec3 kGravity(0.0, 0.0, -imu::kGravity_m_s2);

/// A wheeled robot's path: a curve in the plane with a small heave, heading turning 0.6-0.76 rad/s
/// (about 90 deg over the stretch).
struct TruePath {
  static Vec3 p(double t) { return Vec3(1.5 * std::sin(0.5 * t), 1.0 - std::cos(0.5 * t), 0.02 * std::sin(2.0 * t)); }
  static Vec3 v(double t) {
    return Vec3(0.75 * std::cos(0.5 * t), 0.5 * std::sin(0.5 * t), 0.04 * std::cos(2.0 * t));
  }
  static Vec3 a(double t) {
    return Vec3(-0.375 * std::sin(0.5 * t), 0.25 * std::cos(0.5 * t), -0.08 * std::sin(2.0 * t));
  }
  static double yaw(double t) { return 0.6 * t + 0.2 * std::sin(0.8 * t); }
  static double yawRate(double t) { return 0.6 + 0.16 * std::cos(0.8 * t); }
  static Mat3 R(double t) { return so3Exp(Vec3(0.0, 0.0, yaw(t))); }
  static SE3 T_w_b(double t) { return SE3(R(t), p(t)); }
};

SE3 cameraInBody() { return SE3(so3Exp(Vec3(-M_PI / 2.0, 0.0, -M_PI / 2.0)), Vec3(0.05, 0.0, 0.12)); }

/// IMU samples of the path with biases `bias`, every kImuDt over [0, 4.1] s; with noise_seed > 0
/// white noise of the default ImuNoise densities (per sample sigma = density / sqrt(kImuDt)).
ImuSamples imuSamples(const imu::ImuBias& bias, unsigned noise_seed = 0) {
  const imu::ImuNoise noise;
  std::mt19937 rng(noise_seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto white = [&](double density) {
    const double sigma = noise_seed > 0 ? density / std::sqrt(kImuDt) : 0.0;
    return Vec3(sigma * normal(rng), sigma * normal(rng), sigma * normal(rng));
  };
  ImuSamples samples;
  for (int i = 0; i * kImuDt <= 4.1; ++i) {
    const double t = i * kImuDt;
    ImuSample s;
    s.t_s = t;
    s.gyro_rad_s = Vec3(0.0, 0.0, TruePath::yawRate(t)) + bias.b_g;
    s.acc_m_s2 = TruePath::R(t).transpose() * (TruePath::a(t) - kGravity) + bias.b_a;
    s.gyro_rad_s += white(noise.gyro_density);
    s.acc_m_s2 += white(noise.acc_density);
    samples.push_back(s);
  }
  return samples;
}

struct Scenario {
  std::vector<CarriedSample> samples;
  imu::ImuBias true_bias;
  imu::ImuBias estimated_bias;  // what tracking had at the last tracked frame
};

/// Frames at 30 Hz; the ones of [1.0, 3.5) s carried: dead-reckoned from the last tracked frame's
/// true state (its velocity off by `dv0`) with the estimated biases; the frame at 3.5 s anchored at
/// its true pose, with its dead-reckoned pose for the blend. Every frame has its IMU data.
Scenario turningStretch(const Vec3& acc_bias_error, const Vec3& gyro_bias_error, const Vec3& dv0,
                        unsigned noise_seed = 0) {
  Scenario s;
  s.true_bias.b_g = Vec3(0.002, -0.001, 0.003);
  s.true_bias.b_a = Vec3(0.05, -0.08, 0.1);
  s.estimated_bias.b_g = s.true_bias.b_g - gyro_bias_error;
  s.estimated_bias.b_a = s.true_bias.b_a - acc_bias_error;
  const ImuSamples imu_samples = imuSamples(s.true_bias, noise_seed);
  const SE3 T_b_c = cameraInBody();
  imu::NavState dead_reckoned;
  for (int k = 0; k < kFrames; ++k) {
    const double t = k * kFrameDt;
    CarriedSample sample;
    sample.t_s = t;
    auto data = std::make_shared<CarriedImu>();
    data->bias = s.estimated_bias;
    data->g_w = kGravity;
    data->T_b_c = T_b_c;
    std::shared_ptr<imu::Preintegrated> pim;
    if (k > 0) {
      pim = std::make_shared<imu::Preintegrated>(s.estimated_bias, imu::ImuNoise{});
      pim->integrate(imu::samplesInInterval(imu_samples, t - kFrameDt, t));
      data->from_previous = pim;
    }
    SE3 T_w_b = TruePath::T_w_b(t);
    data->v_w_b = TruePath::v(t);
    if (k == kFirstCarried - 1) {
      dead_reckoned.R_w_b = T_w_b.rotationMatrix();
      dead_reckoned.p_w_b = T_w_b.translation();
      dead_reckoned.v_w_b = TruePath::v(t) + dv0;
      data->v_w_b = dead_reckoned.v_w_b;
    } else if (k >= kFirstCarried && k <= kAnchored) {
      dead_reckoned = imu::predict(dead_reckoned, *pim, s.estimated_bias, kGravity);
      if (k < kAnchored) {
        sample.carried = true;
        T_w_b = SE3(dead_reckoned.R_w_b, dead_reckoned.p_w_b);
        data->v_w_b = dead_reckoned.v_w_b;
      } else {
        sample.T_w_c_dead_reckoned = SE3(dead_reckoned.R_w_b, dead_reckoned.p_w_b) * T_b_c;
      }
    }
    sample.T_w_c = T_w_b * T_b_c;
    sample.imu = std::move(data);
    s.samples.push_back(std::move(sample));
  }
  return s;
}

double maxPositionError_m(const std::vector<CarriedSample>& samples) {
  double max_m = 0.0;
  for (const CarriedSample& s : samples) {
    const Vec3 p_true = (TruePath::T_w_b(s.t_s) * cameraInBody()).translation();
    max_m = std::max(max_m, (s.T_w_c.translation() - p_true).norm());
  }
  return max_m;
}

double maxRotationError_deg(const std::vector<CarriedSample>& samples) {
  double max_rad = 0.0;
  for (const CarriedSample& s : samples) {
    const Mat3 R_true = (TruePath::T_w_b(s.t_s) * cameraInBody()).rotationMatrix();
    max_rad = std::max(max_rad, so3Log(s.T_w_c.rotationMatrix() * R_true.transpose()).norm());
  }
  return max_rad * 180.0 / M_PI;
}

CarriedCorrectionOptions correction(bool bridge, double margin_s = 0.5) {
  CarriedCorrectionOptions options;
  options.bridge = bridge;
  options.margin_s = margin_s;
  return options;
}

const Vec3 kAccBiasError(0.06, -0.05, 0.02);  // m/s^2, 1-2 sigma of Tracking.AccBiasSigma
const Vec3 kGyroBiasError(0.0, 0.0005, 0.0015);  // rad/s

TEST(CarriedBridge, TurningStretchWithAnAccelerometerBiasErrorIsRecovered) {
  const Scenario scenario = turningStretch(kAccBiasError, kGyroBiasError, Vec3(0.004, -0.003, 0.0));
  const double dead_reckoned_m = maxPositionError_m(scenario.samples);
  ASSERT_GT(dead_reckoned_m, 0.15);  // 0.5 |db_a| t^2 over 2.5 s, turned through 90 deg

  std::vector<CarriedSample> blended = scenario.samples;
  const CarriedCorrectionCounts blend_counts = correctCarriedStretches(blended, correction(false));
  EXPECT_EQ(blend_counts.blended, 1);
  EXPECT_EQ(blend_counts.bridged, 0);
  std::vector<CarriedSample> bridged = scenario.samples;
  const CarriedCorrectionCounts bridge_counts = correctCarriedStretches(bridged, correction(true));
  EXPECT_EQ(bridge_counts.bridged, 1);
  EXPECT_EQ(bridge_counts.blended, 0);

  const double blend_m = maxPositionError_m(blended);
  const double bridge_m = maxPositionError_m(bridged);
  // The blend's world-frame quadratic cannot follow an error that turns with the robot.
  EXPECT_GT(blend_m, 0.02);    // 21.7 mm (dead reckoning 251 mm)
  EXPECT_LT(bridge_m, 0.002);  // 0.12 mm
  EXPECT_LT(maxRotationError_deg(bridged), 0.02);
  EXPECT_GT(maxRotationError_deg(blended), 0.05);
  // The frames outside the stretch are untouched.
  for (std::size_t k = 0; k < bridged.size(); ++k) {
    if (bridged[k].carried) continue;
    EXPECT_EQ(bridged[k].T_w_c.translation(), scenario.samples[k].T_w_c.translation()) << k;
  }
}

TEST(CarriedBridge, FindsTheBiasesOfTheStretch) {
  const Scenario scenario = turningStretch(kAccBiasError, kGyroBiasError, Vec3::Zero());
  const std::optional<CarriedBridgeResult> result =
      bridgeCarriedStretch(scenario.samples, kFirstCarried, kAnchored, CarriedBridgeOptions{});
  ASSERT_TRUE(result.has_value());
  EXPECT_EQ(result->margin_before, 15);  // 0.5 s at 30 Hz
  EXPECT_EQ(result->margin_after, 15);
  EXPECT_EQ(result->T_w_c.size(), static_cast<std::size_t>(kAnchored - kFirstCarried));
  EXPECT_LT((result->bias.b_a - scenario.true_bias.b_a).norm(), 0.1 * kAccBiasError.norm());
  EXPECT_LT((result->bias.b_g - scenario.true_bias.b_g).norm(), 0.1 * kGyroBiasError.norm());
}

TEST(CarriedBridge, NoisyImuStillBeatsTheBlend) {
  for (unsigned seed = 1; seed <= 3; ++seed) {
    const Scenario scenario = turningStretch(kAccBiasError, kGyroBiasError, Vec3(0.004, -0.003, 0.0), seed);
    std::vector<CarriedSample> blended = scenario.samples;
    correctCarriedStretches(blended, correction(false));
    std::vector<CarriedSample> bridged = scenario.samples;
    EXPECT_EQ(correctCarriedStretches(bridged, correction(true)).bridged, 1) << seed;
    const double blend_m = maxPositionError_m(blended);
    const double bridge_m = maxPositionError_m(bridged);
    EXPECT_GT(blend_m, 0.015) << seed;  // 20-23 mm
    EXPECT_LT(bridge_m, 0.004) << seed;  // 0.6-1.7 mm
    EXPECT_LT(bridge_m, 0.25 * blend_m) << seed;
  }
}

TEST(CarriedBridge, HoldsBothEnds) {
  // The anchored frame 3 cm off its true place (the map's error there): the stretch ends there,
  // and still starts at the last tracked frame.
  Scenario scenario = turningStretch(kAccBiasError, kGyroBiasError, Vec3::Zero());
  const Vec3 offset_w(0.03, -0.01, 0.0);
  CarriedSample& anchored = scenario.samples[kAnchored];
  anchored.T_w_c = SE3(anchored.T_w_c.rotationMatrix(), anchored.T_w_c.translation() + offset_w);
  CarriedBridgeOptions options;
  options.margin_s = 0.0;  // the margins after A would contradict it
  const std::optional<CarriedBridgeResult> result =
      bridgeCarriedStretch(scenario.samples, kFirstCarried, kAnchored, options);
  ASSERT_TRUE(result.has_value());
  auto truth = [](int k) { return (TruePath::T_w_b(k * kFrameDt) * cameraInBody()).translation(); };
  const Vec3 first_error = result->T_w_c.front().translation() - truth(kFirstCarried);
  const Vec3 last_error = result->T_w_c.back().translation() - truth(kAnchored - 1);
  EXPECT_LT(first_error.norm(), 0.002);
  EXPECT_LT((last_error - offset_w).norm(), 0.004);
}

TEST(CarriedBridge, WithoutMarginsStillBeatsTheBlend) {
  const Scenario scenario = turningStretch(kAccBiasError, kGyroBiasError, Vec3(0.004, -0.003, 0.0));
  std::vector<CarriedSample> blended = scenario.samples;
  correctCarriedStretches(blended, correction(false));
  std::vector<CarriedSample> bridged = scenario.samples;
  EXPECT_EQ(correctCarriedStretches(bridged, correction(true, 0.0)).bridged, 1);
  EXPECT_LT(maxPositionError_m(bridged), 0.5 * maxPositionError_m(blended));
}

TEST(CarriedBridge, MissingImuDataFallsBackToTheBlend) {
  const Scenario scenario = turningStretch(kAccBiasError, kGyroBiasError, Vec3::Zero());
  std::vector<CarriedSample> blended = scenario.samples;
  correctCarriedStretches(blended, correction(false));
  std::vector<CarriedSample> samples = scenario.samples;
  samples[60].imu.reset();  // a carried frame without its data
  const CarriedCorrectionCounts counts = correctCarriedStretches(samples, correction(true));
  EXPECT_EQ(counts.bridged, 0);
  EXPECT_EQ(counts.blended, 1);
  EXPECT_EQ(maxPositionError_m(samples), maxPositionError_m(blended));
  // A preintegration that does not span the time between the frames (a frame left out) does not link.
  std::vector<CarriedSample> gap = scenario.samples;
  gap.erase(gap.begin() + 70);
  EXPECT_FALSE(bridgeCarriedStretch(gap, kFirstCarried, kAnchored - 1, CarriedBridgeOptions{}).has_value());
  // The anchored frame in another world: not bridged.
  std::vector<CarriedSample> other_world = scenario.samples;
  other_world[kAnchored].world = 7;
  EXPECT_FALSE(bridgeCarriedStretch(other_world, kFirstCarried, kAnchored, CarriedBridgeOptions{}).has_value());
}

TEST(CarriedBridge, RetentionKeepsCarriedFramesAndTheirMarginsOnly) {
  // 0.49 s: 14.7 frame intervals, so no frame lies on a margin's edge (0.5 s would put one there,
  // kept or not as the rounding of k / 30 goes).
  CarriedImuRetention retention(0.49);
  std::vector<bool> kept(300, false);
  auto add = [&](std::size_t k, bool carried, std::uint64_t map) {
    for (const auto& entry : retention.add(k, k * kFrameDt, carried, map, std::make_shared<CarriedImu>())) {
      EXPECT_FALSE(kept[entry.first]) << entry.first;
      kept[entry.first] = true;
    }
    EXPECT_LE(retention.numPending(), 16u);  // at most the margin of frames held back
  };
  // Tracked 0-99, carried 100-129, tracked 130-199 in map 0; carried 200-209, then a new map (1)
  // tracked 210-239 (a possible floating map), then map 0 again.
  for (std::size_t k = 0; k < 300; ++k) {
    const bool carried = (k >= 100 && k < 130) || (k >= 200 && k < 210);
    add(k, carried, k >= 210 && k < 240 ? 1 : 0);
  }
  auto count = [&](std::size_t from, std::size_t to) {
    int n = 0;
    for (std::size_t k = from; k < to; ++k) n += kept[k] ? 1 : 0;
    return n;
  };
  EXPECT_EQ(count(0, 85), 0);     // long before the stretch
  EXPECT_EQ(count(85, 100), 15);  // the margin before it, the last tracked frame included
  EXPECT_EQ(count(100, 130), 30);
  EXPECT_EQ(count(130, 144), 14);  // the margin after it
  EXPECT_EQ(count(144, 185), 0);
  EXPECT_EQ(count(185, 240), 55);  // margin, carried, the other map's frames
  EXPECT_EQ(count(240, 254), 14);  // and the margin after them
  EXPECT_EQ(count(254, 300), 0);
}

}  // namespace
}  // namespace ltlo::system
