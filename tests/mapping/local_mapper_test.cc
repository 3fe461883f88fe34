// LocalMapper driven synchronously from the tracking callback on a simulated static sequence
// (issue 6): local BA keeps the trajectory at least as good as visual odometry, the map is
// maintained (fusion, point and keyframe culling), and the IMU initialisation recovers gravity,
// velocities and the gyroscope bias.
#include <gtest/gtest.h>

#include <cstdio>

#include "ltlo/imu/inertial_residual.h"
#include "mapping_test_fixture.h"

namespace ltlo::mapping::test {
namespace {

TEST_F(MappingOnSimulatedSequence, LocalBundleAdjustmentIsNotWorseThanVisualOdometry) {
  RunConfig vo_config;
  vo_config.with_mapper = false;
  const RunResult vo = run(vo_config);
  RunConfig ba_config;
  ba_config.options = mapperOptions(/*use_imu=*/false);
  const RunResult ba = run(ba_config);
  std::printf("VO: ATE rmse %.4f m max %.4f m, keyframe ATE %.4f m, %d keyframes\n", vo.ate.error_m.rmse,
              vo.ate.error_m.max, vo.keyframe_ate.error_m.rmse, vo.keyframes_in_map);
  std::printf("mapping: ATE rmse %.4f m max %.4f m, keyframe ATE %.4f m; keyframes %d created %d in map, "
              "%d points; BA runs %d, fused %d, culled points %d, culled keyframes %d; per keyframe %.1f ms "
              "mean (max %.1f), local BA %.1f ms\n",
              ba.ate.error_m.rmse, ba.ate.error_m.max, ba.keyframe_ate.error_m.rmse, ba.keyframes_created,
              ba.keyframes_in_map, ba.points_in_map, ba.counters.local_ba_runs, ba.counters.fused_points,
              ba.counters.culled_points, ba.counters.culled_keyframes, ba.mapping_mean_ms, ba.mapping_max_ms,
              ba.local_ba_mean_ms);
  EXPECT_EQ(vo.ok, vo.frames);
  EXPECT_EQ(ba.ok, ba.frames);
  EXPECT_EQ(ba.counters.keyframes_processed, ba.keyframes_created);
  EXPECT_EQ(ba.counters.local_ba_runs, ba.keyframes_created - 1);  // all but the first keyframe
  EXPECT_GT(ba.counters.fused_points, 0);
  EXPECT_GT(ba.counters.culled_points, 0);
  EXPECT_EQ(ba.keyframes_in_map, ba.keyframes_created - ba.counters.culled_keyframes);
  EXPECT_EQ(ba.counters.imu_initialisations, 0);
  EXPECT_LT(ba.ate.error_m.rmse, 0.03);
  EXPECT_LT(ba.ate.error_m.rmse, vo.ate.error_m.rmse * 1.1 + 0.002);
  EXPECT_LT(ba.keyframe_ate.error_m.rmse, vo.keyframe_ate.error_m.rmse * 1.1 + 0.002);
}

TEST_F(MappingOnSimulatedSequence, ImuInitialisationRecoversGravityVelocitiesAndGyroBias) {
  RunConfig config;
  config.options = mapperOptions(/*use_imu=*/true);
  const RunResult result = run(config);
  ASSERT_TRUE(result.imu.initialised);
  // The map frame is the simulator's gravity-aligned world (first pose from ground truth).
  const double gravity_error_deg = angleDeg(result.imu.g_w, imu::gravityWorld());
  double velocity_sq = 0.0, velocity_max = 0.0;
  int velocity_count = 0;
  for (const KeyFrameVelocity& kf : result.velocities) {
    if (kf.t_s < result.imu_initialised_at_s) continue;
    const double error = (kf.v_w_b - trueVelocity(kf.t_s)).norm();
    velocity_sq += error * error;
    velocity_max = std::max(velocity_max, error);
    ++velocity_count;
  }
  const double velocity_rmse = velocity_count > 0 ? std::sqrt(velocity_sq / velocity_count) : 0.0;
  const imu::ImuBias truth = trueBias(result.velocities.back().t_s);
  const double gyro_bias_error = (result.imu.bias.b_g - truth.b_g).norm();
  const double acc_bias_error = (result.imu.bias.b_a - truth.b_a).norm();
  std::printf("IMU initialised at t = %.2f s, %d estimates (generation %llu): gravity error %.3f deg, velocity "
              "rmse %.4f m/s max %.4f m/s over %d keyframes, |b_g err| %.5f rad/s (true |b_g| %.5f), |b_a err| "
              "%.4f m/s^2 (true |b_a| %.4f)\n",
              result.imu_initialised_at_s, result.counters.imu_initialisations,
              static_cast<unsigned long long>(result.imu.generation), gravity_error_deg, velocity_rmse, velocity_max,
              velocity_count, gyro_bias_error, truth.b_g.norm(), acc_bias_error, truth.b_a.norm());
  std::printf("visual-inertial mapping: ATE rmse %.4f m max %.4f m, keyframe ATE %.4f m, keyframes %d (%d in "
              "map), BA runs %d, culled keyframes %d, per keyframe %.1f ms mean, local BA %.1f ms\n",
              result.ate.error_m.rmse, result.ate.error_m.max, result.keyframe_ate.error_m.rmse,
              result.keyframes_created, result.keyframes_in_map, result.counters.local_ba_runs,
              result.counters.culled_keyframes, result.mapping_mean_ms, result.local_ba_mean_ms);
  EXPECT_EQ(result.ok, result.frames);
  EXPECT_EQ(result.counters.imu_initialisations, 3);  // first initialisation and two refinements
  EXPECT_EQ(result.imu.generation, static_cast<std::uint64_t>(result.counters.imu_initialisations));
  EXPECT_LT(gravity_error_deg, 0.5);  // measured 0.13 deg
  EXPECT_GE(velocity_count, 5);
  EXPECT_LT(velocity_rmse, 0.05);
  // Measured 1.0e-3 rad/s against a true |b_g| of 2.7e-3, and 0.018 m/s^2 against a true |b_a| of
  // 0.055 (the bias priors follow the IMU noise, ImuInit.BiasPriorSamples; the visual-inertial
  // refinements separate b_a from the tilt of gravity): better than assuming no bias.
  EXPECT_LT(gyro_bias_error, truth.b_g.norm());
  EXPECT_LT(acc_bias_error, 0.6 * truth.b_a.norm());
  EXPECT_LT(result.ate.error_m.rmse, 0.03);
}

}  // namespace
}  // namespace ltlo::mapping::test
