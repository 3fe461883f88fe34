#pragma once
/// Zero-velocity (standstill) detection from the IMU alone (issue 32), a windowed test in the spirit
/// of the SHOE / GLRT detectors of foot-mounted navigation: over the last `window_s` of samples,
///   G = mean_k |omega_k - b_g|^2 / (3 sigma_g^2),   A = mean_k |f_k - mean(f)|^2 / (3 sigma_a^2),
/// with sigma = noise density * sqrt(rate), the white noise of one reading (IMU.NoiseGyro,
/// IMU.NoiseAcc, IMU.Frequency). At rest both are about 1 (each a chi2 over 3N dof, divided by 3N);
/// any motion of a wheeled robot (its rotation, its vibration, the acceleration of starting or
/// stopping) drives them far above. Still means: both below `threshold` over the whole window and
/// over the newest samples alone (the last frame's), so the start of motion is seen within a frame
/// rather than diluted by the window. The gyroscope is compared with the bias estimate, not its own
/// mean, so a slow steady turn is not taken for rest.
#include <deque>

#include "ltlo/core/calib.h"
#include "ltlo/core/eigen_types.h"
#include "ltlo/core/imu_sample.h"

namespace ltlo::imu {

struct ZeroVelocityOptions {
  double window_s = 0.3;     ///< samples the test looks at (s)
  double threshold = 3.0;    ///< largest G and A still called rest (1 = white noise at the density)
  double noise_gyro = 1.7e-4;  ///< rad/s/sqrt(Hz)
  double noise_acc = 2.0e-3;   ///< m/s^2/sqrt(Hz)
  double rate_hz = 200.0;      ///< Hz

  /// The calibration's densities and rate with the given window and threshold.
  static ZeroVelocityOptions fromCalib(const ImuCalib& calib, double window_s, double threshold);
};

/// The test statistics of the last update.
struct ZeroVelocityStatistics {
  double gyro_ratio = 0.0;       ///< G over the window
  double acc_ratio = 0.0;        ///< A over the window
  double newest_gyro_ratio = 0.0;  ///< G over the newest samples only
  double newest_acc_ratio = 0.0;   ///< A over the newest samples (deviation from the window mean)
  int samples = 0;               ///< in the window
  bool still = false;
};

/// Not thread-safe (the tracking thread owns one).
class ZeroVelocityDetector {
 public:
  explicit ZeroVelocityDetector(const ZeroVelocityOptions& options);

  /// Adds the samples of one frame interval (stamp order; samples at or before the newest one held
  /// are skipped, so the shared end of two consecutive intervals counts once) and tests the window
  /// with the gyro bias b_g. Still only once the window is full (its samples span window_s).
  bool update(const ImuSamples& samples, const Vec3& b_g);
  /// Forgets the window (a gap in the IMU, a new map).
  void reset();

  bool still() const { return statistics_.still; }
  const ZeroVelocityStatistics& statistics() const { return statistics_; }
  /// Mean accelerometer and gyro reading over the window (m/s^2, rad/s; zero when empty).
  Vec3 meanAcc() const;
  Vec3 meanGyro() const;
  /// Stamp of the oldest sample in the window (0 when empty); the first full window holds every
  /// sample since the start or reset().
  double windowStart_s() const { return window_.empty() ? 0.0 : window_.front().t_s; }

  /// Everything the next update() depends on (a run resumed from its saved state, issue 31).
  struct State {
    std::deque<ImuSample> window;
    bool tested = false;
    ZeroVelocityStatistics statistics;
  };
  State state() const { return {window_, tested_, statistics_}; }
  void restore(State state);

 private:
  ZeroVelocityOptions options_;
  std::deque<ImuSample> window_;
  bool tested_ = false;  ///< a full window has been tested (from then on old samples leave)
  ZeroVelocityStatistics statistics_;
};

}  // namespace ltlo::imu
