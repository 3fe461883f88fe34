#pragma once
/// One static score gamma in [0, 1] per depth cluster (thesis Eq. 59-64 estimate them; 1 = static).
/// The no-depth cluster K always scores 1: without depth it cannot be judged, and treating it as
/// static keeps features there usable as in a static SLAM system.
#include <opencv2/core/mat.hpp>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/segmentation/cluster_map.h"

namespace ltlo::segmentation {

/// A plain value (K + 1 scores); not synchronised.
class StaticScores {
 public:
  StaticScores() = default;
  /// gamma_k for the K depth clusters, each in [0, 1]; the no-depth score 1 is appended.
  explicit StaticScores(const std::vector<double>& gamma_per_cluster);
  /// All K + 1 scores 1 (no segmentation yet: everything is static).
  static StaticScores allStatic(int num_clusters);

  /// K (the number of depth clusters; values() has K + 1 entries)
  int numClusters() const { return static_cast<int>(gamma_.size()) - 1; }
  const std::vector<double>& values() const { return gamma_; }
  /// gamma of a label in [0, K]
  double gamma(int label) const;
  /// Sets gamma of a depth cluster k in [0, K) to a value in [0, 1].
  void setGamma(int k, double gamma);
  /// gamma >= threshold
  bool isStatic(int label, double threshold) const { return gamma(label) >= threshold; }

  /// gamma of the cluster under pixel (u, v) / under the pixel nearest to a keypoint u_px.
  double atPixel(const ClusterMap& clusters, int u, int v) const;
  double atPoint(const ClusterMap& clusters, const Vec2& u_px) const;

  /// CV_8U mask of the label image's size: 0 where the pixel's cluster is static
  /// (gamma >= threshold), 255 where dynamic (the masks/ convention of DATA_FORMAT.md).
  cv::Mat staticMask(const ClusterMap& clusters, double threshold) const;
  /// Share of the image's pixels whose cluster is static, in [0, 1].
  double staticAreaRatio(const ClusterMap& clusters, double threshold) const;

 private:
  std::vector<double> gamma_;
};

}  // namespace ltlo::segmentation
