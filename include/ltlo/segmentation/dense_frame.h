#pragma once
/// DenseFrame: one RGB-D frame prepared for the dense initial state and segmentation (thesis Eq.
/// 59-64): an intensity + depth pyramid whose base is the working resolution (Dense.Resolution,
/// QVGA for VGA input), each level half the previous. Everything per pixel that does not depend on
/// the motion is computed once, when the frame arrives:
///   - for the frame's role as the *current* frame i: the pixels with depth as structure-of-arrays
///     (3-D point in the camera frame, intensity, the weights w_I and w_D of Eq. 64, cluster label);
///   - for its role as the *previous* frame i-1 of the next frame: an interleaved lookup table
///     (I, dI/du, dI/dv, D, dD/du, dD/dv, depth valid) per pixel, sampled bilinearly at the warped
///     positions W(u, T) of Eq. 63, and the cluster labels per level (the temporal prior).
/// Buffers are reused between frames (build() reallocates only when the size changes).
#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "ltlo/core/camera.h"
#include "ltlo/core/settings.h"

namespace ltlo::segmentation {

/// Pinhole intrinsics of one pyramid level (pixel centres at integer coordinates, as PinholeCamera).
struct LevelCamera {
  int width = 0;
  int height = 0;
  float fx = 0.0f, fy = 0.0f, cx = 0.0f, cy = 0.0f;
};

/// Channels of DenseLevel::lookup, per pixel.
enum LookupChannel : int {
  kLookupI = 0,   ///< intensity in [0, 1]
  kLookupIu = 1,  ///< dI/du per level pixel
  kLookupIv = 2,  ///< dI/dv
  kLookupD = 3,   ///< depth, m (0 without)
  kLookupDu = 4,  ///< dD/du of the pixel's own surface, m per level pixel (not across a discontinuity)
  kLookupDv = 5,  ///< dD/dv, likewise
  kLookupValid = 6,  ///< 1 with depth, 0 without (bilinear: 1 only when all four taps have depth)
  /// 1 when the 2 x 2 cell with this pixel at its top left lies on one surface (all four depths
  /// within the depth gap), else 0; read at the cell, not interpolated
  kLookupSmoothCell = 7,
  kLookupChannels = 8,
};

struct DenseFrameOptions {
  /// level-0 size, px (Dense.Resolution); the input size must be an integer multiple of it
  int width = 320;
  int height = 240;
  /// levels (Dense.PyramidLevels)
  int num_levels = 3;
  /// finer levels keep only their images and labels (no lookup table, no per-pixel arrays): the
  /// solver does not work on them (Dense.FinestLevel)
  int finest_solved_level = 0;
  /// Eq. 64: w_I = 1 / (lambda_I sigma_I^2 + |grad I|), intensities in [0, 1], gradient per level
  /// pixel (Seg.NoiseWeightIntensity, Seg.SigmaIntensity)
  double lambda_intensity = 10.0;
  double sigma_intensity = 0.01;
  /// Eq. 64: w_D = 1 / (lambda_D sigma_D(z)^2 + |grad D|), with the depth noise growing with the
  /// square of the depth, sigma_D(z) = sigma_D * (z / 1 m)^2 (Seg.NoiseWeightDepth, Seg.SigmaDepth)
  double lambda_depth = 10.0;
  double sigma_depth_m = 0.005;
  /// Downsampling keeps the mean of a block's depths when they lie within
  /// min(max_gap_m, gap_at_zero_m + gap_growth_per_m z^2) of each other, else the nearest one
  /// (never a depth between two surfaces); the same gap as the cluster graph V_i.
  double gap_at_zero_m = 0.02;
  double gap_growth_per_m = 0.05;
  double max_gap_m = 0.15;

  static DenseFrameOptions from(const SegmentationOptions& segmentation, const DenseOptions& dense);
};

/// One pyramid level of a DenseFrame.
struct DenseLevel {
  LevelCamera camera;
  cv::Mat intensity;  ///< CV_32F, [0, 1]
  cv::Mat depth_m;    ///< CV_32F, 0 = no depth
  cv::Mat labels;     ///< CV_8U cluster labels (setLabels); label K = no depth
  /// For each pixel, the level-below pixel (index in its block, 0..3 in raster order) whose depth
  /// and label this pixel took (level 0: unused).
  std::vector<std::uint8_t> child;
  /// kLookupChannels floats per pixel, row-major (the previous-frame role).
  std::vector<float> lookup;
  // The current-frame role: pixels with depth, structure of arrays.
  std::vector<float> x_m, y_m, z_m;  ///< back-projected point in the camera frame
  std::vector<float> intensity_at;   ///< I_i(u)
  std::vector<float> weight_I;       ///< w_I of Eq. 64
  std::vector<float> weight_D;       ///< w_D of Eq. 64
  std::vector<int> pixel;            ///< row * width + col
  std::vector<std::uint8_t> label;   ///< cluster of the pixel (setLabels)

  int numPixelsWithDepth() const { return static_cast<int>(pixel.size()); }
};

/// Not thread-safe; built by the segmentation worker, then read by the tracking thread.
class DenseFrame {
 public:
  /// Builds every level from an input colour (CV_8UC3 BGR or CV_8UC1) and depth image (CV_32F m)
  /// of `input_camera`'s size, an integer multiple `scale` of (options.width, options.height).
  void build(const cv::Mat& color, const cv::Mat& depth_m, const PinholeCamera& input_camera,
             const DenseFrameOptions& options);
  /// Level-0 cluster labels (CV_8U, level-0 size; label num_clusters = no depth): propagated to the
  /// coarser levels (each pixel takes the label of the pixel its depth came from) and to the
  /// per-pixel arrays.
  void setLabels(const cv::Mat& labels, int num_clusters);

  int numLevels() const { return static_cast<int>(levels_.size()); }
  const DenseLevel& level(int l) const { return levels_[static_cast<std::size_t>(l)]; }
  /// input px per level-0 px
  int scale() const { return scale_; }
  int numClusters() const { return num_clusters_; }
  bool empty() const { return levels_.empty(); }

  /// The level-0 camera of an input camera for a level-0 size (integer scale; asserts).
  static LevelCamera levelCamera(const PinholeCamera& input_camera, int scale);

 private:
  std::vector<DenseLevel> levels_;
  int scale_ = 1;
  int num_clusters_ = 0;
  cv::Mat gray_, gray_float_;  // input-size grey scratch
};

}  // namespace ltlo::segmentation
