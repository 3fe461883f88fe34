#pragma once
/// Fast depth over-segmentation at the working resolution (thesis section 4.2 / 6.2.1; QVGA for
/// VGA input): K-means on back-projected 3-D points from K seeds on a uniform grid, a few Lloyd
/// iterations on a subsample (one pixel per sample_step x sample_step block), then one assignment
/// of every pixel with depth to the nearest centre among the clusters of the samples around it.
/// The same pass writes 8-bit labels (pixels without depth get label K), counts the pixels of each
/// cluster and builds the connectivity graph V_i (clusters that touch in the image and are close in
/// 3-D across the shared boundary, without a crease between their planes). Buffers are kept between calls: no allocation per frame once
/// the sizes are known.
#include <memory>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "ltlo/core/camera.h"
#include "ltlo/core/eigen_types.h"
#include "ltlo/core/settings.h"
#include "ltlo/segmentation/cluster_map.h"

namespace ltlo::segmentation {

struct DepthKMeansOptions {
  /// K (Seg.Clusters), at most kMaxClusters (cluster_map.h)
  int num_clusters = 24;
  /// Lloyd iterations on the subsample after seeding (Seg.KMeansIterations)
  int kmeans_iterations = 3;
  /// One Lloyd sample per sample_step_px x sample_step_px block (its centre pixel, or the first
  /// pixel with depth in it); 4 at QVGA gives 80x60 samples, about 200 per cluster.
  int sample_step_px = 4;
  /// V_i: a boundary pixel pair links its two clusters when the depth difference across it is
  /// below min(max_gap_m, gap_at_zero_m + gap_growth_per_m * z^2), z its mean depth in m (depth
  /// noise and the depth step between neighbouring pixels on slanted surfaces grow with z^2).
  double gap_at_zero_m = 0.02;
  /// 1/m
  double gap_growth_per_m = 0.05;
  /// cap of the threshold, m (Seg.MaxNeighbourGap)
  double max_gap_m = 0.15;
  /// V_i also needs the two clusters to lie on one smooth surface: their plane normals (from the
  /// samples' 3-D scatter) differ by less than this angle, rad. A box standing on the floor touches
  /// it at the same depth, but across a crease of 90 degrees; two patches of one wall or floor do not
  /// fold. Clusters that are not planar (their scatter has no clearly smallest axis) keep their links.
  double max_crease_angle_rad = 0.6;

  /// K, iterations and the gap cap from Seg.*.
  static DepthKMeansOptions from(const SegmentationOptions& segmentation);
  /// Depth-gap threshold of V_i for a boundary at depth z_m, m.
  double gapThreshold(double z_m) const;
};

/// The clusters of one depth image (a plain value; DepthKMeans::cluster fills it in place).
struct DepthClusters {
  /// CV_8U, the depth image's size; values in [0, num_clusters], num_clusters = no depth.
  cv::Mat labels;
  /// K actually used (the requested K unless fewer pixels have depth; 0 when none has)
  int num_clusters = 0;
  /// pixels per label (num_clusters + 1 entries, the last counts the pixels without depth)
  std::vector<int> pixel_counts;
  /// V_i, each undirected pair once (a < b), sorted by (a, b)
  std::vector<ClusterEdge> edges;
  /// mean 3-D point of each depth cluster in the camera frame, m (num_clusters entries)
  std::vector<Vec3> centroids_c;
};

namespace detail {
struct KMeansBuffers;
}

/// Not thread-safe (one caller at a time; the segmentation worker thread owns one); movable.
class DepthKMeans {
 public:
  explicit DepthKMeans(const DepthKMeansOptions& options);
  ~DepthKMeans();
  DepthKMeans(DepthKMeans&&) noexcept;
  DepthKMeans& operator=(DepthKMeans&&) noexcept;

  /// Clusters `depth_m` (CV_32F metres, 0 or non-finite = no reading) seen by `camera` (whose size
  /// must match). Writes `out` (labels are reallocated only when out->labels is not a CV_8U image
  /// of the right size, so a caller may hand in a recycled buffer). Deterministic.
  void cluster(const cv::Mat& depth_m, const PinholeCamera& camera, DepthClusters* out);

  const DepthKMeansOptions& options() const { return options_; }

 private:
  DepthKMeansOptions options_;
  std::unique_ptr<detail::KMeansBuffers> buffers_;
};

}  // namespace ltlo::segmentation
