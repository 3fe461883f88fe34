#pragma once
/// The segmentation of one image (DESIGN.md, "Static scores are stored where they are used"): an
/// 8-bit cluster label image at a reduced resolution (QVGA for VGA input), one static score gamma
/// per cluster (thesis Eq. 59-64 in tracking, refined by the robust VIBA of Eq. 50-58 in local
/// mapping), the pixel count of every cluster, the cluster connectivity graph V_i (the smoothness
/// term of Eq. 54) and the depth image local mapping needs for the gamma prior of Eq. 56. Carried
/// by every Frame and KeyFrame.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

namespace ltlo::map {

/// Cluster labels of one image and their static scores Gamma = {gamma_0 .. gamma_K}.
/// Labels are in [0, K]: 0..K-1 are depth clusters, K (the last) is the "no depth" cluster, whose
/// gamma stays 1. With empty labels the whole image is one cluster with score gamma[0] (the
/// trivially static seam). A plain value type; not synchronised (KeyFrame guards its copy).
struct ClusterSegmentation {
  /// CV_8U, (input width / scale) x (input height / scale), values in [0, numClusters()); empty = one
  /// cluster over the whole image.
  cv::Mat labels;
  /// Input pixels per label pixel along each axis (2 for VGA input segmented at QVGA): the keypoint
  /// at input coordinates (x, y) has the label at (x / scale, y / scale).
  int scale = 1;
  /// Static score per cluster in [0, 1]; gamma.size() = K + 1 (just {gamma_0} with empty labels).
  std::vector<double> gamma;
  /// Label pixels per cluster (numClusters() entries); may be empty, then counted on demand.
  std::vector<int> pixel_counts;
  /// V_i: pairs (a, b), a < b, of depth clusters that touch in the image and are close in 3-D.
  std::vector<std::pair<int, int>> neighbours;
  /// Depth for Eq. 56 in local mapping: CV_16U millimetres (0 = no reading), at
  /// (input size / depth_scale); may be empty (frames that are not keyframes need not keep it).
  cv::Mat depth_mm;
  /// Input pixels per depth_mm pixel along each axis.
  int depth_scale = 1;

  /// One cluster over the image with gamma = 1 (the trivially static seam; labels empty).
  static ClusterSegmentation allStatic();

  int numClusters() const { return static_cast<int>(gamma.size()); }
  /// Index of the no-depth cluster K (numClusters() - 1); -1 with empty labels (no such cluster).
  int noDepthCluster() const { return labels.empty() ? -1 : numClusters() - 1; }
  /// Cluster of the input pixel nearest to (x_px, y_px) (input coordinates; clamped to the label
  /// image); 0 when labels is empty.
  int clusterAt(float x_px, float y_px) const {
    if (labels.empty()) return 0;
    // The nearest input pixel (half up, as std::lround for these non-negative coordinates; a
    // negative one clamps to 0 either way), then the label pixel covering it. Inline, without a
    // libm call: Eq. 56 samples every window point and probe in every window keyframe.
    const int col = std::clamp(static_cast<int>(static_cast<double>(x_px) + 0.5) / scale, 0, labels.cols - 1);
    const int row = std::clamp(static_cast<int>(static_cast<double>(y_px) + 0.5) / scale, 0, labels.rows - 1);
    return labels.at<std::uint8_t>(row, col);
  }
  /// gamma of `cluster`; 1 for a cluster outside [0, numClusters()) (no evidence of motion).
  double gammaOf(int cluster) const;
  /// Depth in metres at input coordinates (x_px, y_px) from depth_mm (nearest sample); 0 when there
  /// is no reading or no depth image.
  double depthAt_m(double x_px, double y_px) const {
    // x_px <= -0.5 would round to a negative pixel (std::lround); above it, truncating x + 0.5 is
    // the nearest pixel, half up.
    if (depth_mm.empty() || x_px <= -0.5 || y_px <= -0.5) return 0.0;
    const long col = static_cast<long>(x_px + 0.5) / depth_scale, row = static_cast<long>(y_px + 0.5) / depth_scale;
    if (col >= depth_mm.cols || row >= depth_mm.rows) return 0.0;
    return 1e-3 * depth_mm.at<std::uint16_t>(static_cast<int>(row), static_cast<int>(col));
  }
  /// Static area (Loop.MinStaticRatio compares against it): the share of the pixels with depth
  /// whose cluster has gamma >= static_threshold, in [0, 1]. No-depth pixels count neither as
  /// static nor in the total. With empty labels: 1 when gamma[0] passes, else 0; 0 when no pixel
  /// has depth.
  double staticAreaRatio(double static_threshold) const;
  /// CV_8U mask at the label resolution: 255 where the pixel's cluster has gamma < static_threshold
  /// (dynamic), 0 elsewhere (the masks/ convention of DATA_FORMAT.md). Empty labels give a
  /// rows x cols mask (pass the input size) filled by gamma[0].
  cv::Mat dynamicMask(double static_threshold, int rows = 0, int cols = 0) const;
  /// Bytes held by the images and tables (the per-keyframe memory figure).
  std::size_t memoryBytes() const;
  /// LTLO_ASSERTs: labels CV_8U, labels in [0, numClusters()), gamma in [0, 1], pixel_counts size,
  /// neighbours in range with a < b, depth_mm CV_16U, scales >= 1.
  void validate() const;
};

}  // namespace ltlo::map
