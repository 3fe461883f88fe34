// Preintegration against the project's simulator, through the sequence files: the noise-free IMU
// written by `simulate` and read back by the sequence reader reproduces the ground-truth relative
// motion between keyframe-spaced frames (issue 6, imu/ acceptance).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "ltlo/core/imu_sample.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/sim/simulator.h"

namespace ltlo::imu {
namespace {

namespace fs = std::filesystem;

TEST(ImuOnSimulatedSequence, NoiseFreeImuReproducesGroundTruthBetweenKeyframes) {
  const fs::path dir = fs::temp_directory_path() / ("ltlo_imu_sim_" + std::to_string(::getpid()));
  sim::SimOptions options;
  options.width_px = 160;
  options.height_px = 120;
  options.scenario = sim::Scenario::kStatic;
  options.seed = 3;
  options.duration_s = 3.0;
  options.noise_free = true;
  sim::Simulator simulator(options);
  sim::writeSequence(simulator, dir.string(), 0);

  const io::SequenceReader reader = io::SequenceReader::open(dir.string());
  ASSERT_TRUE(reader.hasImu());
  ASSERT_TRUE(reader.calib().has_imu);
  const SE3 T_b_c = reader.calib().imu.T_b_c;
  const io::Trajectory& gt = reader.groundTruth();
  ASSERT_EQ(static_cast<int>(gt.size()), reader.frameCount());
  const ImuNoise noise = ImuNoise::fromCalib(reader.calib().imu);

  // Keyframe-like spacing: 10 frames (0.33 s). Poses come from the files; the velocity at i, which
  // groundtruth.txt does not hold, from the simulator's analytic trajectory.
  auto T_w_b = [&](int k) { return gt[k].T_w_x * T_b_c.inverse(); };
  double worst_p_m = 0.0, worst_R_deg = 0.0;
  for (int i = 0; i + 10 < reader.frameCount(); i += 10) {
    const int j = i + 10;
    NavState state_i;
    state_i.R_w_b = T_w_b(i).rotationMatrix();
    state_i.p_w_b = T_w_b(i).translation();
    state_i.v_w_b = simulator.trajectory().state(gt[i].t_s).v_w_b;
    Preintegrated pim(ImuBias{}, noise);
    pim.integrate(imuSamplesBetween(reader.imu(), gt[i].t_s, gt[j].t_s));
    EXPECT_NEAR(pim.dt_s(), gt[j].t_s - gt[i].t_s, 1e-9);
    const NavState predicted = predict(state_i, pim, ImuBias{}, gravityWorld());
    worst_p_m = std::max(worst_p_m, (predicted.p_w_b - T_w_b(j).translation()).norm());
    worst_R_deg = std::max(
        worst_R_deg,
        so3Log(Mat3(predicted.R_w_b.transpose() * T_w_b(j).rotationMatrix())).norm() * 180.0 / M_PI);
  }
  EXPECT_LT(worst_p_m, 1e-3);
  EXPECT_LT(worst_R_deg, 0.01);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace ltlo::imu
