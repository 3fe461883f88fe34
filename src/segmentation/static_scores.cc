#include "ltlo/segmentation/static_scores.h"

#include "ltlo/core/assert.h"

namespace ltlo::segmentation {

StaticScores::StaticScores(const std::vector<double>& gamma_per_cluster)
    : gamma_(gamma_per_cluster) {
  for (size_t k = 0; k < gamma_.size(); ++k) {
    LTLO_ASSERT(gamma_[k] >= 0.0 && gamma_[k] <= 1.0,
                "gamma_" << k << " = " << gamma_[k] << ", expected a value in [0, 1]");
  }
  gamma_.push_back(1.0);
}

StaticScores StaticScores::allStatic(int num_clusters) {
  LTLO_ASSERT(num_clusters >= 0, "num_clusters = " << num_clusters);
  return StaticScores(std::vector<double>(num_clusters, 1.0));
}

double StaticScores::gamma(int label) const {
  LTLO_ASSERT(label >= 0 && label < static_cast<int>(gamma_.size()),
              "label " << label << " outside [0, " << numClusters() << "]");
  return gamma_[label];
}

void StaticScores::setGamma(int k, double gamma) {
  LTLO_ASSERT(k >= 0 && k < numClusters(),
              "cluster " << k << " outside [0, " << numClusters() << ")");
  LTLO_ASSERT(gamma >= 0.0 && gamma <= 1.0, "gamma_" << k << " = " << gamma << ", expected [0, 1]");
  gamma_[k] = gamma;
}

double StaticScores::atPixel(const ClusterMap& clusters, int u, int v) const {
  return gamma(clusters.labelAt(u, v));
}

double StaticScores::atPoint(const ClusterMap& clusters, const Vec2& u_px) const {
  return gamma(clusters.labelAt(u_px));
}

cv::Mat StaticScores::staticMask(const ClusterMap& clusters, double threshold) const {
  LTLO_ASSERT(clusters.num_clusters == numClusters(),
              "scores for " << numClusters() << " clusters, map has " << clusters.num_clusters);
  std::vector<uint8_t> mask_of_label(gamma_.size());
  for (size_t k = 0; k < gamma_.size(); ++k) mask_of_label[k] = gamma_[k] >= threshold ? 0 : 255;
  cv::Mat mask(clusters.labels.size(), CV_8U);
  for (int v = 0; v < mask.rows; ++v) {
    const int* label_row = clusters.labels.ptr<int>(v);
    uint8_t* mask_row = mask.ptr<uint8_t>(v);
    for (int u = 0; u < mask.cols; ++u) mask_row[u] = mask_of_label[label_row[u]];
  }
  return mask;
}

double StaticScores::staticAreaRatio(const ClusterMap& clusters, double threshold) const {
  LTLO_ASSERT(clusters.num_clusters == numClusters(),
              "scores for " << numClusters() << " clusters, map has " << clusters.num_clusters);
  LTLO_ASSERT(clusters.pixel_counts.size() == gamma_.size(),
              "pixel_counts has " << clusters.pixel_counts.size() << " entries, expected "
                                  << gamma_.size());
  long long total = 0, num_static = 0;
  for (size_t k = 0; k < gamma_.size(); ++k) {
    total += clusters.pixel_counts[k];
    if (gamma_[k] >= threshold) num_static += clusters.pixel_counts[k];
  }
  return total > 0 ? static_cast<double>(num_static) / static_cast<double>(total) : 1.0;
}

}  // namespace ltlo::segmentation
