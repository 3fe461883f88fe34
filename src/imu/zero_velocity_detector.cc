#include "ltlo/imu/zero_velocity_detector.h"

#include <cmath>
#include <utility>

#include "ltlo/core/assert.h"

namespace ltlo::imu {

ZeroVelocityOptions ZeroVelocityOptions::fromCalib(const ImuCalib& calib, double window_s, double threshold) {
  ZeroVelocityOptions options;
  options.window_s = window_s;
  options.threshold = threshold;
  options.noise_gyro = calib.noise_gyro;
  options.noise_acc = calib.noise_acc;
  options.rate_hz = calib.rate_hz;
  return options;
}

ZeroVelocityDetector::ZeroVelocityDetector(const ZeroVelocityOptions& options) : options_(options) {
  LTLO_ASSERT(options.window_s > 0.0 && options.rate_hz > 0.0 && options.noise_gyro > 0.0 && options.noise_acc > 0.0,
              "zero-velocity detector: window, rate and noise densities must be positive");
}

void ZeroVelocityDetector::reset() {
  window_.clear();
  tested_ = false;
  statistics_ = ZeroVelocityStatistics();
}

void ZeroVelocityDetector::restore(State state) {
  window_ = std::move(state.window);
  tested_ = state.tested;
  statistics_ = state.statistics;
}

Vec3 ZeroVelocityDetector::meanAcc() const {
  Vec3 sum = Vec3::Zero();
  for (const ImuSample& s : window_) sum += s.acc_m_s2;
  return window_.empty() ? sum : Vec3(sum / static_cast<double>(window_.size()));
}

Vec3 ZeroVelocityDetector::meanGyro() const {
  Vec3 sum = Vec3::Zero();
  for (const ImuSample& s : window_) sum += s.gyro_rad_s;
  return window_.empty() ? sum : Vec3(sum / static_cast<double>(window_.size()));
}

bool ZeroVelocityDetector::update(const ImuSamples& samples, const Vec3& b_g) {
  int added = 0;
  for (const ImuSample& s : samples) {
    if (!window_.empty() && s.t_s <= window_.back().t_s) continue;
    if (!s.gyro_rad_s.allFinite() || !s.acc_m_s2.allFinite()) continue;
    window_.push_back(s);
    ++added;
  }
  // Samples leave the window only once a full window has been tested, so the first test covers
  // every sample since the start (or the reset): rest then reaches back to the first sample.
  if (tested_) {
    while (window_.size() > 1 && window_.back().t_s - window_[1].t_s >= options_.window_s) window_.pop_front();
  }
  statistics_ = ZeroVelocityStatistics();
  statistics_.samples = static_cast<int>(window_.size());
  // The window is full once its samples span window_s (less one sample period of slack).
  const double span_s = window_.empty() ? 0.0 : window_.back().t_s - window_.front().t_s;
  if (added == 0 || span_s < options_.window_s - 1.5 / options_.rate_hz) return false;
  tested_ = true;
  const double var_gyro = options_.noise_gyro * options_.noise_gyro * options_.rate_hz;
  const double var_acc = options_.noise_acc * options_.noise_acc * options_.rate_hz;
  const Vec3 mean_acc = meanAcc();
  double gyro_sum = 0.0, acc_sum = 0.0, newest_gyro = 0.0, newest_acc = 0.0;
  const std::size_t first_newest = window_.size() - static_cast<std::size_t>(added);
  for (std::size_t k = 0; k < window_.size(); ++k) {
    const double g = (window_[k].gyro_rad_s - b_g).squaredNorm();
    const double a = (window_[k].acc_m_s2 - mean_acc).squaredNorm();
    gyro_sum += g;
    acc_sum += a;
    if (k >= first_newest) {
      newest_gyro += g;
      newest_acc += a;
    }
  }
  const double n = static_cast<double>(window_.size());
  statistics_.gyro_ratio = gyro_sum / (3.0 * n * var_gyro);
  statistics_.acc_ratio = acc_sum / (3.0 * (n - 1.0) * var_acc);  // one mean estimated
  statistics_.newest_gyro_ratio = newest_gyro / (3.0 * added * var_gyro);
  statistics_.newest_acc_ratio = newest_acc / (3.0 * added * var_acc);
  const double t = options_.threshold;
  statistics_.still = statistics_.gyro_ratio < t && statistics_.acc_ratio < t && statistics_.newest_gyro_ratio < t &&
                      statistics_.newest_acc_ratio < t;
  return statistics_.still;
}

}  // namespace ltlo::imu
