#pragma once
/// Depth K-means over-segmentation (thesis section 4.2): K seeds on a uniform pixel grid, pixels
/// clustered by their back-projected 3-D points in the camera frame, a few Lloyd iterations.
/// Runs every frame in the tracking thread, so it works on a subsampled depth image and labels
/// the full image from the subsampled result.
#include <memory>
#include <opencv2/core/mat.hpp>

#include "ltlo/core/camera.h"
#include "ltlo/core/settings.h"
#include "ltlo/segmentation/cluster_map.h"

namespace ltlo::segmentation {

struct DepthClusteringOptions {
  /// K (Seg.Clusters)
  int num_clusters = 24;
  /// Lloyd iterations after seeding (Seg.KMeansIterations); they run on every other working
  /// sample in both directions (a quarter), then one assignment labels all working samples
  int kmeans_iterations = 3;
  /// The image is subsampled by the largest integer step that keeps it at least this size, px
  /// (Dense.Resolution, 320x240); smaller inputs are clustered at full resolution.
  int working_width = 320;
  int working_height = 240;
  /// Connectivity: a boundary pixel pair links its two clusters when the depth difference across
  /// it is below min(max_gap_m, gap_at_zero_m + gap_growth_per_m * z^2), z its mean depth in m.
  /// The z^2 term follows the depth noise and the depth step between neighbouring pixels on
  /// slanted surfaces, both of which grow with z^2.
  double gap_at_zero_m = 0.02;
  /// 1/m
  double gap_growth_per_m = 0.05;
  /// cap of the threshold (Seg.MaxNeighbourGap)
  double max_gap_m = 0.15;
  /// Neighbouring samples lie on one smooth surface when their depth difference is below the gap
  /// threshold and the surface folds by less than this angle between them (3-D tangents into and
  /// out of the link), rad: it separates a box from the floor it stands on or from a wall corner.
  double max_crease_angle_rad = 0.6;
  /// A piece of a cluster cut off from the rest by depth steps or creases, touching no other
  /// cluster smoothly, becomes a cluster of its own (freeing a label by merging two small adjacent
  /// clusters) when it holds at least this share of the valid working samples; smaller pieces
  /// keep their label.
  double min_island_share = 0.005;

  /// Takes K, iterations and the gap cap from Seg.*, the working size from Dense.Resolution.
  static DepthClusteringOptions from(const SegmentationOptions& segmentation,
                                     const DenseOptions& dense);
  /// Depth-gap threshold for a boundary at depth z_m, m.
  double gapThreshold(double z_m) const;
};

namespace detail {
struct ClusteringBuffers;
}

/// Keeps its working buffers between calls (reallocating them every frame costs more than the
/// clustering), so one instance serves one thread at a time: not thread-safe, movable.
class DepthClustering {
 public:
  explicit DepthClustering(const DepthClusteringOptions& options);
  ~DepthClustering();
  DepthClustering(DepthClustering&&) noexcept;
  DepthClustering& operator=(DepthClustering&&) noexcept;

  /// Clusters `depth_m` (CV_32F, metres, 0 or non-finite = no reading) taken with `camera`
  /// (whose size must match the image). Deterministic: same input, same labels.
  ClusterMap cluster(const cv::Mat& depth_m, const PinholeCamera& camera);

  const DepthClusteringOptions& options() const { return options_; }

 private:
  DepthClusteringOptions options_;
  std::unique_ptr<detail::ClusteringBuffers> buffers_;
};

}  // namespace ltlo::segmentation
