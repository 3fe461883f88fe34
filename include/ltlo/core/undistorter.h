#pragma once
/// Undistorter: the precomputed tables that take a distorted camera's measurements onto the ideal
/// pinhole grid of the same K and size (CameraModel::pinhole()), built once per run.
///   - keypoints: a per-pixel table of the ideal position of every raw pixel, read bilinearly at a
///     keypoint's sub-pixel position (no iterative solve per keypoint; the table's own values come
///     from CameraModel::undistortPixel, exact at pixel centres, about 1e-4 px between them for a
///     24 px corner distortion);
///   - images: cv::remap maps from each ideal pixel to its raw position (linear for intensity and
///     colour, nearest for depth and labels: a depth is never blended across an edge);
///   - back to raw: the ideal position of each raw pixel on a grid `scale` times coarser (the
///     segmentation's label images), for writing masks in the raw image's grid.
/// Ideal pixels with no raw source (beyond the image after undistortion) are 0 in remapped images.
/// Immutable after construction: const methods are thread-safe.
#include <opencv2/core.hpp>
#include <vector>

#include "ltlo/core/camera_model.h"

namespace ltlo {

class Undistorter {
 public:
  /// The identity (no lens): active() is false and nothing is precomputed.
  Undistorter() = default;
  explicit Undistorter(const CameraModel& model);

  /// True when the lens distorts (otherwise callers keep the pinhole path, bit for bit).
  bool active() const { return active_; }
  const CameraModel& model() const { return model_; }

  /// Ideal pixel of a raw sub-pixel position (bilinear in the table; positions outside the image
  /// are clamped to its border cell, so the value is the border's extrapolation).
  void undistortPoint(float x_raw, float y_raw, float* x_ideal, float* y_ideal) const;
  /// Raw image -> ideal grid of the same size; `interpolation` cv::INTER_LINEAR or cv::INTER_NEAREST.
  void toIdeal(const cv::Mat& raw, cv::Mat* ideal, int interpolation) const;
  /// cv::remap maps (CV_32FC2) of raw pixel -> its position on the ideal grid scaled by 1 / scale
  /// (pixel centres as PinholeCamera::scaled), for cv::remap of a coarse ideal image to the raw grid.
  cv::Mat rawToIdealMap(int scale) const;

  /// Fraction of the ideal grid with a raw source (1 for a lens that only shrinks the image).
  double idealCoverage() const { return ideal_coverage_; }

 private:
  CameraModel model_;
  bool active_ = false;
  int width_ = 0, height_ = 0;
  std::vector<float> ideal_xy_;      ///< per raw pixel, row-major: ideal x, y
  cv::Mat ideal_to_raw_linear_[2];   ///< fixed-point remap maps (CV_16SC2, CV_16UC1)
  cv::Mat ideal_to_raw_nearest_;     ///< CV_16SC2
  double ideal_coverage_ = 1.0;
};

}  // namespace ltlo
