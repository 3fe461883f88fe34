#pragma once
/// Result of the depth over-segmentation of one frame (thesis section 4.2): a cluster label per
/// pixel, each cluster's 3-D centroid and the connectivity graph V of touching, 3-D-close clusters
/// (the neighbourhood of the smoothness term, Eq. 28 / Eq. 54).
#include <opencv2/core/mat.hpp>
#include <vector>

#include "ltlo/core/eigen_types.h"

namespace ltlo::segmentation {

/// Two clusters that touch in the image and are close in 3-D across that boundary (a < b).
struct ClusterEdge {
  int a = 0;
  int b = 0;
  /// number of 4-neighbour boundary pixel pairs (at the working resolution) that passed the
  /// depth-gap test; a measure of the length of the shared boundary
  int num_boundary_pairs = 0;
};

/// The most depth clusters of one frame (Seg.Clusters): the label images written for a run are
/// 8-bit and label K is "no depth", so K <= 255 and a per-label table has kMaxClusterLabels entries.
constexpr int kMaxClusters = 255;
constexpr int kMaxClusterLabels = kMaxClusters + 1;

/// Cluster labels of one depth image. Labels 0..K-1 are depth clusters, label K is "no depth".
/// A plain value: copyable, no shared state.
struct ClusterMap {
  /// CV_32S, same size as the input depth; values in [0, num_clusters]
  cv::Mat labels;
  /// K actually used (the requested K unless there were fewer valid depth pixels)
  int num_clusters = 0;
  /// centroid of each cluster in the camera frame, m (K entries; mean of its working-resolution
  /// points; an empty cluster keeps its last centre)
  std::vector<Vec3> centroids_c;
  /// pixels per label at the input resolution (K + 1 entries, the last counts no-depth pixels)
  std::vector<int> pixel_counts;
  /// connectivity graph V, each undirected pair once, sorted by (a, b)
  std::vector<ClusterEdge> edges;

  /// The label of pixels without valid depth (= num_clusters).
  int noDepthLabel() const { return num_clusters; }
  /// Label at pixel (u, v) (column, row); asserts inside the image.
  int labelAt(int u, int v) const;
  /// Label at the pixel nearest to u_px (pixel centres at integer coordinates); asserts inside.
  int labelAt(const Vec2& u_px) const;
  /// True when clusters a and b are linked in V.
  bool connected(int a, int b) const;
  /// Indices of the clusters linked to k in V.
  std::vector<int> neighbours(int k) const;
};

}  // namespace ltlo::segmentation
