#include "ltlo/tracking/imu_dead_reckoning.h"

namespace ltlo::tracking {

ImuDeadReckoning::ImuDeadReckoning(double t0_s, double replay_s) : replay_s_(replay_s) {
  Step first;
  first.t_s = t0_s;
  first.after = state_;
  history_.push_back(std::move(first));
}

std::optional<imu::RestEstimate> ImuDeadReckoning::restEstimate() const {
  if (!state_.g_w || state_.rest_s <= 0.0) return std::nullopt;
  return imu::RestEstimate{*state_.g_w, state_.b_g, state_.rest_s};
}

void ImuDeadReckoning::restUpdate(const imu::Preintegrated* imu, bool rest_begins, State* state) {
  // Pose held, velocity zero; the rest's mean readings give the gyro bias and gravity (the
  // preintegration subtracts its linearisation bias, so gravity is taken against the same).
  state->v_w_b.setZero();
  if (rest_begins) {
    state->rest_gyro_sum.setZero();
    state->rest_acc_sum.setZero();
    state->rest_s = 0.0;
  }
  if (imu == nullptr) return;
  for (const imu::Preintegrated::Step& step : imu->steps()) {
    state->rest_gyro_sum += step.dt_s * step.gyro_mean_rad_s;
    state->rest_acc_sum += step.dt_s * step.acc_mean_m_s2;
    state->rest_s += step.dt_s;
  }
  if (state->rest_s <= 0.0) return;
  state->b_g = state->rest_gyro_sum / state->rest_s;
  state->g_w = -(state->T_w_b.rotationMatrix() * (state->rest_acc_sum / state->rest_s - imu->bias().b_a));
}

void ImuDeadReckoning::integrate(const imu::Preintegrated* imu, State* state) {
  if (imu == nullptr || imu->dt_s() <= 0.0) return;
  imu::ImuBias bias = imu->bias();
  bias.b_g = state->b_g;
  const Mat3 R_i = state->T_w_b.rotationMatrix();
  const Mat3 R_j = R_i * imu->correctedDeltaR(bias);
  if (!state->g_w) {
    // No rest seen: the orientation from the gyroscope, the position held.
    state->T_w_b = SE3(R_j, state->T_w_b.translation());
    return;
  }
  const Vec3& g_w = *state->g_w;
  const double dt = imu->dt_s();
  const Vec3 p_j =
      state->T_w_b.translation() + state->v_w_b * dt + 0.5 * dt * dt * g_w + R_i * imu->correctedDeltaP(bias);
  state->v_w_b += dt * g_w + R_i * imu->correctedDeltaV(bias);
  state->T_w_b = SE3(R_j, p_j);
}

void ImuDeadReckoning::replayFromTrustedRest(double t_s) {
  // The newest rest step old enough, else the oldest rest step held (the history is trimmed to
  // about replay_s, so that one is nearly as old).
  std::size_t anchor = history_.size();
  for (std::size_t k = 0; k < history_.size(); ++k) {
    if (!history_[k].rest) continue;
    if (history_[k].t_s <= t_s - replay_s_ || anchor == history_.size()) anchor = k;
    if (history_[k].t_s > t_s - replay_s_) break;
  }
  if (anchor == history_.size()) return;
  state_ = history_[anchor].after;
  for (std::size_t k = anchor + 1; k < history_.size(); ++k) {
    Step& step = history_[k];
    integrate(step.imu ? &*step.imu : nullptr, &state_);
    step.rest = false;
    step.after = state_;
  }
}

void ImuDeadReckoning::propagate(double t_s, const imu::Preintegrated* imu, bool at_rest) {
  const bool was_rest = !history_.empty() && history_.back().rest;
  if (!at_rest && was_rest) replayFromTrustedRest(t_s);
  if (at_rest) {
    restUpdate(imu, !was_rest, &state_);
  } else {
    integrate(imu, &state_);
  }
  Step step;
  step.t_s = t_s;
  if (imu != nullptr) step.imu = *imu;
  step.rest = at_rest;
  step.after = state_;
  history_.push_back(std::move(step));
  // Keep the steps of the last replay_s and the one before them (the anchor a replay may need).
  while (history_.size() > 2 && history_[1].t_s < t_s - replay_s_) history_.pop_front();
}

}  // namespace ltlo::tracking
