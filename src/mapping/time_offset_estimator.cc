#include "time_offset_estimator.h"

#include <algorithm>
#include <cmath>

#include "ltlo/core/lie.h"

namespace ltlo::mapping {

namespace {

// The link's rotation residual at x = (shift, b_g).
Vec3 rotationResidual(const TimeOffsetLink& link, const Vec4& x) {
  const double shift = x(0);
  const Vec3 b_g = x.tail<3>();
  imu::ImuBias bias = link.pim.bias();
  bias.b_g = b_g;
  const Vec3 w_begin = link.pim.firstGyro() - b_g;
  const Vec3 w_end = link.pim.lastGyro() - b_g;
  const Mat3 delta_R = so3Exp(-w_begin * (shift - link.pim.shiftBegin_s())) * link.pim.correctedDeltaR(bias) *
                       so3Exp(w_end * (shift - link.pim.shiftEnd_s()));
  return so3Log(delta_R.transpose() * link.R_w_b_begin.transpose() * link.R_w_b_end);
}

}  // namespace

std::optional<TimeOffsetEstimate> estimateTimeOffset(const std::vector<TimeOffsetLink>& links, double initial_shift_s,
                                                     const Vec3& gyro_bias, const TimeOffsetOptions& options) {
  if (links.size() < 3) return std::nullopt;
  // Rotation information of each link (the preintegration's phi block).
  std::vector<Mat3> information(links.size());
  for (std::size_t k = 0; k < links.size(); ++k) {
    const Mat3 covariance = links[k].pim.covariance().block<3, 3>(0, 0);
    information[k] = covariance.inverse();
    if (!information[k].allFinite()) return std::nullopt;
  }
  Vec4 x;
  x << initial_shift_s, gyro_bias;
  const double prior_info_shift = 1.0 / (options.prior_sigma_s * options.prior_sigma_s);
  const double prior_info_bias = 1.0 / (options.gyro_bias_sigma_rad_s * options.gyro_bias_sigma_rad_s);
  Mat4 H = Mat4::Zero();
  for (int iteration = 0; iteration < options.iterations; ++iteration) {
    H.setZero();
    Vec4 g = Vec4::Zero();
    for (std::size_t k = 0; k < links.size(); ++k) {
      const Vec3 r = rotationResidual(links[k], x);
      // Central differences: the model is four scalars, and the residual is smooth in them.
      Eigen::Matrix<double, 3, 4> J;
      for (int p = 0; p < 4; ++p) {
        const double eps = p == 0 ? 1e-5 : 1e-6;
        Vec4 plus = x, minus = x;
        plus(p) += eps;
        minus(p) -= eps;
        J.col(p) = (rotationResidual(links[k], plus) - rotationResidual(links[k], minus)) / (2.0 * eps);
      }
      const double whitened = std::sqrt(r.dot(information[k] * r));
      const double weight = whitened <= options.huber_whitened ? 1.0 : options.huber_whitened / whitened;
      H += weight * J.transpose() * information[k] * J;
      g += weight * J.transpose() * information[k] * r;
    }
    H(0, 0) += prior_info_shift;
    g(0) += prior_info_shift * (x(0) - options.prior_shift_s);
    H.block<3, 3>(1, 1) += prior_info_bias * Mat3::Identity();
    g.tail<3>() += prior_info_bias * (x.tail<3>() - gyro_bias);
    const Vec4 step = H.ldlt().solve(-g);
    if (!step.allFinite()) return std::nullopt;
    x += step;
    x(0) = std::clamp(x(0), -options.max_abs_shift_s, options.max_abs_shift_s);
    if (std::abs(step(0)) < 1e-7 && step.tail<3>().norm() < 1e-9) break;
  }
  TimeOffsetEstimate estimate;
  estimate.shift_s = x(0);
  estimate.gyro_bias = x.tail<3>();
  estimate.links = static_cast<int>(links.size());
  const Mat4 covariance = H.inverse();
  if (!covariance.allFinite() || covariance(0, 0) <= 0.0) return std::nullopt;
  estimate.sigma_s = std::sqrt(covariance(0, 0));
  double sum = 0.0;
  for (const TimeOffsetLink& link : links) sum += rotationResidual(link, x).squaredNorm();
  estimate.rms_rad = std::sqrt(sum / static_cast<double>(links.size()));
  return estimate;
}

std::vector<TimeOffsetLink> chainLinks(const map::Map& map, const map::KeyFrame& newest, int max_links) {
  std::vector<TimeOffsetLink> links;
  Mat3 R_end = newest.T_w_b().rotationMatrix();
  std::optional<imu::Preintegrated> pim = newest.imuFromPrevious();
  map::KeyFrameId previous_id = newest.previousKeyFrame();
  while (pim && static_cast<int>(links.size()) < max_links) {
    const std::shared_ptr<map::KeyFrame> previous = map.keyFrame(previous_id);
    if (!previous || previous->isBad()) break;
    const Mat3 R_begin = previous->T_w_b().rotationMatrix();
    links.push_back(TimeOffsetLink{R_begin, R_end, std::move(*pim)});
    R_end = R_begin;
    pim = previous->imuFromPrevious();
    previous_id = previous->previousKeyFrame();
  }
  return links;
}

int moveChainBoundaries(const map::Map& map, map::KeyFrameId newest_processed, double shift_s, double min_move_s) {
  int moved = 0;
  for (const std::shared_ptr<map::KeyFrame>& kf : map.keyFrames()) {
    if (kf->isBad()) continue;
    const std::shared_ptr<map::KeyFrame> next = map.keyFrame(kf->nextKeyFrame());
    if (!next || next->isBad() || next->id().value > newest_processed.value) continue;
    if (next->previousKeyFrame() != kf->id()) continue;
    // The test on the links' timing first: copying a preintegration (its measurements) for every
    // keyframe of a long run's map costs more than the moves (issue 32).
    const std::optional<map::KeyFrame::ImuLinkTiming> earlier_timing = kf->imuLinkTiming();
    const std::optional<map::KeyFrame::ImuLinkTiming> later_timing = next->imuLinkTiming();
    if (!earlier_timing || !later_timing) continue;
    const double move_s = shift_s - earlier_timing->shift_end_s;
    if (std::abs(move_s) <= min_move_s) continue;
    if (std::abs(move_s) >= 0.5 * std::min(earlier_timing->dt_s, later_timing->dt_s)) continue;
    std::optional<imu::Preintegrated> earlier = kf->imuFromPrevious();
    std::optional<imu::Preintegrated> later = next->imuFromPrevious();
    if (!earlier || !later) continue;
    imu::Preintegrated::moveBoundary(*earlier, *later, shift_s);
    kf->setImuFromPrevious(std::move(earlier));
    next->setImuFromPrevious(std::move(later));
    ++moved;
  }
  return moved;
}

}  // namespace ltlo::mapping
