#include "ltlo/core/imu_sample.h"

#include <algorithm>

#include "ltlo/core/assert.h"

namespace ltlo {

ImuSample interpolateImuSample(const ImuSample& a, const ImuSample& b, double t_s) {
  LTLO_ASSERT(a.t_s <= t_s && t_s <= b.t_s,
              "interpolation time " << t_s << " outside [" << a.t_s << ", " << b.t_s << "]");
  const double span_s = b.t_s - a.t_s;
  const double w = span_s > 0.0 ? (t_s - a.t_s) / span_s : 0.0;
  ImuSample s;
  s.t_s = t_s;
  s.gyro_rad_s = (1.0 - w) * a.gyro_rad_s + w * b.gyro_rad_s;
  s.acc_m_s2 = (1.0 - w) * a.acc_m_s2 + w * b.acc_m_s2;
  return s;
}

ImuSamples imuSamplesBetween(const ImuSamples& imu, double t_begin_s, double t_end_s) {
  ImuSamples out;
  if (imu.empty() || t_end_s < t_begin_s) return out;
  const double begin_s = std::max(t_begin_s, imu.front().t_s);
  const double end_s = std::min(t_end_s, imu.back().t_s);
  if (begin_s > end_s) return out;
  auto by_time = [](const ImuSample& s, double t_s) { return s.t_s < t_s; };
  // First sample at or after begin_s; interpolate the boundary sample from its predecessor.
  auto it = std::lower_bound(imu.begin(), imu.end(), begin_s, by_time);
  if (it->t_s == begin_s) {  // also the case when it is the first sample (begin_s is clipped)
    out.push_back(*it);
  } else {
    out.push_back(interpolateImuSample(*(it - 1), *it, begin_s));
  }
  if (end_s == begin_s) return out;
  for (; it != imu.end() && it->t_s < end_s; ++it) {
    if (it->t_s > begin_s) out.push_back(*it);
  }
  if (it != imu.end() && it->t_s == end_s) {
    out.push_back(*it);
  } else {
    LTLO_ASSERT(it != imu.end() && it != imu.begin(), "IMU interval end outside the stream");
    out.push_back(interpolateImuSample(*(it - 1), *it, end_s));
  }
  return out;
}

}  // namespace ltlo
