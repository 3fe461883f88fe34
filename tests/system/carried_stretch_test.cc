// Smoothing of IMU-carried stretches in the trajectory output (system/carried_stretch.h):
//   - the correction share follows the IMU error model (velocity error: linear, acceleration
//     error: quadratic) and runs from 0 at the last tracked frame to 1 at the anchored one;
//   - a stretch dead-reckoned with a wrong velocity and a wrong acceleration is brought back to
//     the true trajectory exactly when the error model matches, and much closer otherwise;
//   - stretches without an anchored end, or at the start, stay as they were;
//   - floating maps (short, started at the IMU's prediction, never merged) stand in for their
//     parent's world, up a chain of such maps; long or merged maps do not.
#include <gtest/gtest.h>

#include <cmath>

#include "ltlo/system/carried_stretch.h"

namespace ltlo::system {
namespace {

constexpr double kDt = 1.0 / 30.0;

/// True camera pose at t: a constant-acceleration curve with a slow yaw.
SE3 truePose(double t) {
  const Vec3 p(0.5 * t, 0.2 * t + 0.05 * t * t, 0.1 * std::sin(t));
  return SE3(so3Exp(Vec3(0.0, 0.0, 0.3 * t)), p);
}

/// Samples over [0, 4) s; frames in [1, 3) s are carried: posed with a velocity error dv and an
/// acceleration error da from t = 1 s and a rotation drift growing linearly; the frame at 3 s is
/// anchored (true pose) with its dead-reckoned pose.
std::vector<CarriedSample> stretchWithDrift(const Vec3& dv, const Vec3& da, const Vec3& drift_rad_s) {
  std::vector<CarriedSample> samples;
  const double t_start = 1.0 - kDt;  // the last tracked frame
  for (int i = 0; i < 120; ++i) {
    const double t = i * kDt;
    CarriedSample sample;
    sample.t_s = t;
    sample.T_w_c = truePose(t);
    const auto driftedAt = [&](double ti) {
      const double s = ti - t_start;
      const SE3 truth = truePose(ti);
      return SE3(so3Exp(drift_rad_s * s) * truth.rotationMatrix(), truth.translation() + dv * s + 0.5 * da * s * s);
    };
    if (i >= 30 && i < 90) {
      sample.carried = true;
      sample.T_w_c = driftedAt(t);
    } else if (i == 90) {
      sample.T_w_c_dead_reckoned = driftedAt(t);
    }
    samples.push_back(sample);
  }
  return samples;
}

double maxPositionError(const std::vector<CarriedSample>& samples) {
  double max_m = 0.0;
  for (const CarriedSample& s : samples) max_m = std::max(max_m, (s.T_w_c.translation() - truePose(s.t_s).translation()).norm());
  return max_m;
}

double maxRotationError(const std::vector<CarriedSample>& samples) {
  double max_rad = 0.0;
  for (const CarriedSample& s : samples) {
    max_rad = std::max(max_rad, so3Log(s.T_w_c.rotationMatrix() * truePose(s.t_s).rotationMatrix().transpose()).norm());
  }
  return max_rad;
}

TEST(CarriedStretch, CorrectionShareFollowsTheImuErrorModel) {
  EXPECT_DOUBLE_EQ(carriedCorrectionShare(0.0, 2.0, 0.01, 0.03), 0.0);
  EXPECT_DOUBLE_EQ(carriedCorrectionShare(1.0, 2.0, 0.01, 0.03), 1.0);
  EXPECT_DOUBLE_EQ(carriedCorrectionShare(1.5, 2.0, 0.01, 0.03), 1.0);  // clamped
  // Velocity error only: linear; acceleration error only: quadratic.
  EXPECT_NEAR(carriedCorrectionShare(0.3, 2.0, 0.01, 0.0), 0.3, 1e-12);
  EXPECT_NEAR(carriedCorrectionShare(0.3, 2.0, 0.0, 0.03), 0.09, 1e-12);
  // Equal weights (sigma_v^2 = sigma_a^2 T^2 / 4): the mean of both.
  EXPECT_NEAR(carriedCorrectionShare(0.5, 2.0, 0.03, 0.03), 0.5 * (0.5 + 0.25), 1e-12);
  // Longer stretches lean to the quadratic shape, and the share is monotone.
  EXPECT_LT(carriedCorrectionShare(0.5, 6.0, 0.01, 0.03), carriedCorrectionShare(0.5, 1.0, 0.01, 0.03));
  double previous = 0.0;
  for (double tau = 0.05; tau <= 1.0; tau += 0.05) {
    const double share = carriedCorrectionShare(tau, 3.0, 0.01, 0.03);
    EXPECT_GT(share, previous);
    previous = share;
  }
}

TEST(CarriedStretch, AccelerationDriftIsRemovedExactlyWhenTheModelMatches) {
  std::vector<CarriedSample> samples = stretchWithDrift(Vec3::Zero(), Vec3(0.05, -0.03, 0.02), Vec3::Zero());
  ASSERT_GT(maxPositionError(samples), 0.05);  // 0.5 |da| t^2 over 2 s
  EXPECT_EQ(smoothCarriedStretches(samples, 0.0, 0.03), 1);
  EXPECT_LT(maxPositionError(samples), 1e-9);
}

TEST(CarriedStretch, MixedDriftShrinksAndRotationFollows) {
  std::vector<CarriedSample> samples =
      stretchWithDrift(Vec3(0.01, 0.0, -0.01), Vec3(0.04, 0.03, 0.0), Vec3(0.0, 0.0, 0.01));
  const double before_m = maxPositionError(samples);
  const double before_rad = maxRotationError(samples);
  EXPECT_EQ(smoothCarriedStretches(samples, 0.01, 0.03), 1);
  // The error model's split of the end error differs from the true one: what is left is the
  // difference of the two shapes, a fraction of the drift.
  EXPECT_LT(maxPositionError(samples), 0.1 * before_m);
  // The rotation drift grows linearly, the share is nearly quadratic: at most a quarter is left.
  EXPECT_LT(maxRotationError(samples), 0.3 * before_rad);
  // The frames outside the stretch are untouched.
  EXPECT_LT((samples[10].T_w_c.translation() - truePose(samples[10].t_s).translation()).norm(), 1e-12);
  EXPECT_LT((samples[100].T_w_c.translation() - truePose(samples[100].t_s).translation()).norm(), 1e-12);
}

TEST(CarriedStretch, StretchesWithoutAnAnchoredEndStayAsTheyAre) {
  std::vector<CarriedSample> samples = stretchWithDrift(Vec3::Zero(), Vec3(0.05, 0.0, 0.0), Vec3::Zero());
  samples[90].T_w_c_dead_reckoned.reset();  // e.g. the anchored frame lies in another map
  const std::vector<CarriedSample> before = samples;
  EXPECT_EQ(smoothCarriedStretches(samples, 0.01, 0.03), 0);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    EXPECT_EQ(samples[i].T_w_c.translation(), before[i].T_w_c.translation());
  }
  // A stretch at the very start (no tracked frame before it) and one at the end stay too.
  std::vector<CarriedSample> edges(4);
  for (int i = 0; i < 4; ++i) edges[static_cast<std::size_t>(i)].t_s = i * kDt;
  edges[0].carried = true;
  edges[1].T_w_c_dead_reckoned = SE3(Mat3::Identity(), Vec3(1.0, 0.0, 0.0));
  edges[3].carried = true;
  EXPECT_EQ(smoothCarriedStretches(edges, 0.01, 0.03), 0);
  EXPECT_EQ(edges[0].T_w_c.translation(), Vec3::Zero());
}

TEST(CarriedStretch, ShortMapsStartedAtThePredictionFloatInTheirParentsWorld) {
  const map::MapId main(0), short_child(1), grandchild(2), long_child(3), unrooted(4);
  std::unordered_map<map::MapId, MapFrameSpan> maps;
  maps[main] = MapFrameSpan{0.0, 45.0, std::nullopt};
  maps[short_child] = MapFrameSpan{9.8, 10.1, main};        // lost again right after it started
  maps[grandchild] = MapFrameSpan{11.0, 12.0, short_child};  // started from the short one
  maps[long_child] = MapFrameSpan{20.0, 30.0, main};        // tracked for 10 s: its own world
  maps[unrooted] = MapFrameSpan{31.0, 32.0, std::nullopt};  // no prediction placed it
  const auto worlds = floatingMapWorlds(maps, 5.0, 4);
  ASSERT_EQ(worlds.size(), 2u);
  EXPECT_EQ(worlds.at(short_child), main);
  EXPECT_EQ(worlds.at(grandchild), main);
  EXPECT_EQ(worlds.count(long_child), 0u);
  EXPECT_EQ(worlds.count(unrooted), 0u);
  // The chain is followed at most max_depth steps: one step leaves the grandchild at its parent.
  EXPECT_EQ(floatingMapWorlds(maps, 5.0, 1).at(grandchild), short_child);
  // A map whose frames span exactly the limit still floats; beyond it does not.
  maps[short_child].last_t_s = 9.8 + 5.0;
  EXPECT_EQ(floatingMapWorlds(maps, 5.0, 4).count(short_child), 1u);
  maps[short_child].last_t_s = 9.8 + 5.01;
  const auto beyond = floatingMapWorlds(maps, 5.0, 4);
  EXPECT_EQ(beyond.count(short_child), 0u);
  EXPECT_EQ(beyond.at(grandchild), short_child);  // its parent no longer floats: its own world
}

TEST(CarriedStretch, AStretchThroughAFloatingMapIsCorrectedAsOne) {
  // Frames of [1, 3) s: carried, except a few in the middle tracked in a floating map, which
  // System::trajectory() marks carried as well: one stretch, corrected by the anchor at 3 s.
  std::vector<CarriedSample> samples = stretchWithDrift(Vec3(0.02, -0.01, 0.0), Vec3(0.04, 0.03, 0.0), Vec3::Zero());
  const double before_m = maxPositionError(samples);
  ASSERT_GT(before_m, 0.1);
  EXPECT_EQ(smoothCarriedStretches(samples, 0.01, 0.03), 1);
  EXPECT_LT(maxPositionError(samples), 0.25 * before_m);
  // Had the floating frames ended the stretch (tracked, not carried), the frames before them
  // would keep their drift: the first part has no anchored end of its own.
  std::vector<CarriedSample> split = stretchWithDrift(Vec3(0.02, -0.01, 0.0), Vec3(0.04, 0.03, 0.0), Vec3::Zero());
  for (int i = 55; i < 60; ++i) split[static_cast<std::size_t>(i)].carried = false;
  smoothCarriedStretches(split, 0.01, 0.03);
  double first_part_m = 0.0;
  for (int i = 30; i < 55; ++i) {
    const CarriedSample& s = split[static_cast<std::size_t>(i)];
    first_part_m = std::max(first_part_m, (s.T_w_c.translation() - truePose(s.t_s).translation()).norm());
  }
  EXPECT_GT(first_part_m, 0.02);
}

}  // namespace
}  // namespace ltlo::system
