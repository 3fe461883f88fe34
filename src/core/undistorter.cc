#include "ltlo/core/undistorter.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "ltlo/core/assert.h"

namespace ltlo {

Undistorter::Undistorter(const CameraModel& model)
    : model_(model), active_(model.isDistorted()), width_(model.pinhole().width()), height_(model.pinhole().height()) {
  if (!active_) return;
  LTLO_ASSERT(width_ > 1 && height_ > 1, "undistorter for a " << width_ << "x" << height_ << " image");
  ideal_xy_.resize(static_cast<std::size_t>(width_) * height_ * 2);
  for (int r = 0; r < height_; ++r) {
    for (int c = 0; c < width_; ++c) {
      // A validated calibration undistorts every raw pixel (CameraCalib::load checks the border);
      // the raw position is the fallback of a lens fold, which validation refuses.
      const Vec2 u = model_.undistortPixel(Vec2(c, r)).value_or(Vec2(c, r));
      float* out = &ideal_xy_[(static_cast<std::size_t>(r) * width_ + c) * 2];
      out[0] = static_cast<float>(u.x());
      out[1] = static_cast<float>(u.y());
    }
  }
  cv::Mat map(height_, width_, CV_32FC2);
  int covered = 0;
  for (int r = 0; r < height_; ++r) {
    cv::Vec2f* row = map.ptr<cv::Vec2f>(r);
    for (int c = 0; c < width_; ++c) {
      const Vec2 raw = model_.distortPixel(Vec2(c, r));
      row[c] = cv::Vec2f(static_cast<float>(raw.x()), static_cast<float>(raw.y()));
      if (raw.x() > -0.5 && raw.y() > -0.5 && raw.x() < width_ - 0.5 && raw.y() < height_ - 0.5) ++covered;
    }
  }
  ideal_coverage_ = static_cast<double>(covered) / (static_cast<double>(width_) * height_);
  cv::convertMaps(map, cv::noArray(), ideal_to_raw_linear_[0], ideal_to_raw_linear_[1], CV_16SC2, false);
  cv::Mat unused;
  cv::convertMaps(map, cv::noArray(), ideal_to_raw_nearest_, unused, CV_16SC2, true);
}

void Undistorter::undistortPoint(float x_raw, float y_raw, float* x_ideal, float* y_ideal) const {
  if (!active_) {
    *x_ideal = x_raw;
    *y_ideal = y_raw;
    return;
  }
  const float x = std::clamp(x_raw, 0.0f, static_cast<float>(width_ - 1));
  const float y = std::clamp(y_raw, 0.0f, static_cast<float>(height_ - 1));
  const int c0 = std::min(static_cast<int>(x), width_ - 2), r0 = std::min(static_cast<int>(y), height_ - 2);
  // Extrapolates linearly outside the image (fx, fy outside [0, 1]) from the border cell.
  const float fx = x_raw - static_cast<float>(c0), fy = y_raw - static_cast<float>(r0);
  const float* p00 = &ideal_xy_[(static_cast<std::size_t>(r0) * width_ + c0) * 2];
  const float* p01 = p00 + 2;
  const float* p10 = p00 + static_cast<std::size_t>(width_) * 2;
  const float* p11 = p10 + 2;
  for (int k = 0; k < 2; ++k) {
    const float top = p00[k] + fx * (p01[k] - p00[k]);
    const float bottom = p10[k] + fx * (p11[k] - p10[k]);
    (k == 0 ? *x_ideal : *y_ideal) = top + fy * (bottom - top);
  }
}

void Undistorter::toIdeal(const cv::Mat& raw, cv::Mat* ideal, int interpolation) const {
  if (!active_) {
    raw.copyTo(*ideal);
    return;
  }
  LTLO_ASSERT(raw.cols == width_ && raw.rows == height_,
              "image " << raw.cols << "x" << raw.rows << " for a " << width_ << "x" << height_ << " camera");
  if (interpolation == cv::INTER_NEAREST) {
    cv::remap(raw, *ideal, ideal_to_raw_nearest_, cv::noArray(), cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar());
  } else {
    cv::remap(raw, *ideal, ideal_to_raw_linear_[0], ideal_to_raw_linear_[1], cv::INTER_LINEAR, cv::BORDER_CONSTANT,
              cv::Scalar());
  }
}

cv::Mat Undistorter::rawToIdealMap(int scale) const {
  LTLO_ASSERT(scale >= 1, "scale " << scale);
  cv::Mat map(height_, width_, CV_32FC2);
  const float inv = 1.0f / static_cast<float>(scale);
  for (int r = 0; r < height_; ++r) {
    cv::Vec2f* row = map.ptr<cv::Vec2f>(r);
    for (int c = 0; c < width_; ++c) {
      float x = static_cast<float>(c), y = static_cast<float>(r);
      if (active_) {
        const float* p = &ideal_xy_[(static_cast<std::size_t>(r) * width_ + c) * 2];
        x = p[0];
        y = p[1];
      }
      row[c] = cv::Vec2f((x + 0.5f) * inv - 0.5f, (y + 0.5f) * inv - 0.5f);
    }
  }
  return map;
}

}  // namespace ltlo
