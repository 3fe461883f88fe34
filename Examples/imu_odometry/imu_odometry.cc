// imu_odometry: IMU-only dead reckoning of a sequence from its ground-truth initial state.
//
// A baseline that shows how fast a low-cost IMU drifts on its own (zero bias assumed, as before
// IMU initialisation), and an end-to-end check of the reader, the preintegration and the
// simulator's IMU. Writes the camera trajectory T_w_c for every frame in TUM format.
//
//   imu_odometry --sequence DIR --out FILE
#include <cstdio>
#include <exception>
#include <string>

#include <CLI/CLI.hpp>

#include "ltlo/core/errors.h"
#include "ltlo/core/imu_sample.h"
#include "ltlo/core/log.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/io/trajectory_io.h"

namespace {

using namespace ltlo;

int run(const std::string& sequence_dir, const std::string& out_path) {
  const io::SequenceReader reader = io::SequenceReader::open(sequence_dir);
  if (!reader.hasImu()) throw InputError(sequence_dir, 0, "sequence has no IMU data");
  if (!reader.calib().has_imu) throw InputError(sequence_dir + "/calib.yaml", 0, "no IMU.* calibration");
  if (!reader.hasGroundTruth() || reader.groundTruth().size() < 3 || reader.frameCount() < 3) {
    throw InputError(sequence_dir + "/groundtruth.txt", 0,
                     "needs at least 3 ground-truth poses for the initial state");
  }
  const SE3 T_b_c = reader.calib().imu.T_b_c;
  const SE3 T_c_b = T_b_c.inverse();
  const io::Trajectory& gt = reader.groundTruth();

  // Initial body state at the second ground-truth pose; velocity by central difference.
  const SE3 T_w_b0 = gt[0].T_w_x * T_c_b;
  const SE3 T_w_b1 = gt[1].T_w_x * T_c_b;
  const SE3 T_w_b2 = gt[2].T_w_x * T_c_b;
  imu::NavState state;
  state.R_w_b = T_w_b1.rotationMatrix();
  state.p_w_b = T_w_b1.translation();
  state.v_w_b = (T_w_b2.translation() - T_w_b0.translation()) / (gt[2].t_s - gt[0].t_s);
  double t_prev_s = gt[1].t_s;

  const imu::ImuNoise noise = imu::ImuNoise::fromCalib(reader.calib().imu);
  const imu::ImuBias zero_bias;
  io::Trajectory estimate;
  for (int i = 0; i < reader.frameCount(); ++i) {
    const double t_s = reader.frameTime(i);
    if (t_s <= t_prev_s) {
      if (t_s == gt[0].t_s || t_s == gt[1].t_s) {
        const SE3 T_w_b = t_s == gt[0].t_s ? T_w_b0 : T_w_b1;
        estimate.push_back({t_s, T_w_b * T_b_c});
      }
      continue;
    }
    const ImuSamples samples = imuSamplesBetween(reader.imu(), t_prev_s, t_s);
    if (samples.size() >= 2 && samples.back().t_s > samples.front().t_s) {
      imu::Preintegrated pim(zero_bias, noise);
      pim.integrate(samples);
      state = imu::predict(state, pim, zero_bias, imu::gravityWorld());
      t_prev_s = samples.back().t_s;
    }
    estimate.push_back({t_s, SE3(state.R_w_b, state.p_w_b) * T_b_c});
  }
  io::writeTumTrajectory(out_path, estimate);
  log::info("imu_odometry: ", estimate.size(), " poses written to ", out_path);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"IMU-only dead reckoning from the ground-truth initial state (baseline)"};
  std::string sequence_dir, out_path;
  app.add_option("--sequence", sequence_dir, "sequence folder (DATA_FORMAT.md)")->required();
  app.add_option("--out", out_path, "output trajectory (TUM, T_w_c)")->required();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  ltlo::log::initFromEnvironment();
  try {
    return run(sequence_dir, out_path);
  } catch (const ltlo::InputError& e) {
    std::fprintf(stderr, "imu_odometry: %s\n", e.what());
    return 2;
  } catch (const ltlo::ConfigError& e) {
    std::fprintf(stderr, "imu_odometry: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "imu_odometry: error: %s\n", e.what());
    return 1;
  }
}
