// Tracker, part 7: the IMU biases in localisation-only mode (Tracking.LocalisationOnly).
//
// A run in a loaded atlas starts from the biases the earlier run estimated, but an IMU's turn-on
// bias changes from one power-up to the next (by 0.1 m/s^2 between the simulator's seeds, as
// between the days of a MEMS IMU), and half of 0.1 m/s^2 times 8 s squared is 3 m of dead reckoning
// behind a box. With local mapping, the run's own keyframes refine the biases (the IMU
// refinements); localisation only makes no keyframes, so the tracker estimates them itself: the
// frames the map localised become nodes of a sliding window, linked by the IMU between them, and
// the inertial-only optimisation of the IMU initialisation (optim::initializeImu: velocities and one
// bias pair, the nodes' poses and the loaded map's gravity held) runs over it once a second. Its
// biases replace the tracker's as a refinement from local mapping would.
#include <algorithm>
#include <cmath>

#include "ltlo/core/log.h"
#include "ltlo/optim/bundle_adjust.h"
#include "ltlo/tracking/tracker.h"

namespace ltlo::tracking {

namespace {

/// A node of the window every this many seconds of map-localised frames.
constexpr double kBiasNodeIntervalS = 0.25;
/// The window: at most this long, estimated once it spans kBiasMinSpanS, every kBiasEstimateIntervalS.
constexpr double kBiasWindowS = 10.0;
constexpr double kBiasMinSpanS = 3.0;
constexpr double kBiasEstimateIntervalS = 1.0;

bool finite(const optim::ImuInitResult& result) {
  return result.g_w.allFinite() && result.bias.b_a.allFinite() && result.bias.b_g.allFinite() &&
         !result.v_w_b.empty() && result.v_w_b.back().allFinite();
}

}  // namespace

void Tracker::updateLocalisationImu(const map::Frame& frame, bool map_localised) {
  LocalisationImuWindow& window = localisation_imu_;
  if (!frame.imu_from_last_frame) {
    // The IMU chain breaks here: the window starts again.
    const double last_estimate_t_s = window.last_estimate_t_s;
    window = LocalisationImuWindow();
    window.last_estimate_t_s = last_estimate_t_s;
    return;
  }
  if (!window.T_w_b.empty()) {
    if (!window.since_newest) {
      window.since_newest = *frame.imu_from_last_frame;
    } else {
      window.since_newest->append(*frame.imu_from_last_frame);
    }
  }
  const bool node_due = window.t_s.empty() || frame.t_s() - window.t_s.back() >= kBiasNodeIntervalS - 1e-6;
  if (!map_localised || !node_due || !frame.hasPose()) return;
  if (!window.T_w_b.empty()) {
    window.pims.push_back(std::make_shared<const imu::Preintegrated>(std::move(*window.since_newest)));
    window.since_newest.reset();
  }
  window.T_w_b.push_back(frame.T_w_b());
  window.t_s.push_back(frame.t_s());
  while (window.t_s.size() > 2 && window.t_s.back() - window.t_s.front() > kBiasWindowS) {
    window.T_w_b.erase(window.T_w_b.begin());
    window.t_s.erase(window.t_s.begin());
    window.pims.erase(window.pims.begin());
  }
  const double span_s = window.t_s.back() - window.t_s.front();
  // Before the start velocity is known the IMU state waits (tracker_loaded_start.cc).
  if (velocity_unknown_ || span_s < kBiasMinSpanS || frame.t_s() - window.last_estimate_t_s < kBiasEstimateIntervalS) {
    return;
  }
  window.last_estimate_t_s = frame.t_s();

  optim::ImuInitProblem problem;
  problem.T_w_b = window.T_w_b;
  problem.pims = window.pims;
  problem.bias_init = bias_;
  const optim::BiasPriorInformation prior =
      optim::biasPriorInformation(window.pims.front()->noise(), span_s, options_.imu_init.bias_prior_samples);
  problem.gyro_bias_prior_information = prior.gyro;
  problem.acc_bias_prior_information = prior.acc;
  problem.iterations = options_.imu_init.iterations;
  // Gravity is the loaded map's (its run's whole window): held, so the few seconds of localised
  // frames only have to tell the biases, and a horizontal b_a cannot hide in a tilt.
  problem.known_R_w_g = Quat::FromTwoVectors(Vec3(0.0, 0.0, -1.0), g_w_.normalized()).toRotationMatrix();
  const optim::ImuInitResult result = optim::initializeImu(problem);
  if (!finite(result)) {
    log::warn("localisation only: the IMU estimate at t = ", frame.t_s(), " s is not finite; biases kept");
    return;
  }
  log::info("localisation only: IMU over ", window.t_s.size(), " localised frames (", span_s, " s): b_a = (",
            result.bias.b_a.transpose(), ") m/s^2, b_g = (", result.bias.b_g.transpose(), ") rad/s, ",
            "gravity held at the loaded map's");
  setImuInitialised(result.bias, result.g_w, optim::accelerationSigma(result.acceleration_covariance_w));
  // The newest node is this frame: the next frame links to it with the estimate's velocity.
  prev_v_w_b_ = result.v_w_b.back();
  if (last_frame_) last_frame_->setVelocity(prev_v_w_b_);
}

}  // namespace ltlo::tracking
