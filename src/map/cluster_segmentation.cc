#include "ltlo/map/cluster_segmentation.h"

#include <algorithm>
#include <cmath>

#include "ltlo/core/assert.h"

namespace ltlo::map {

ClusterSegmentation ClusterSegmentation::allStatic(int width_px, int height_px) {
  ClusterSegmentation s;
  s.labels = cv::Mat(height_px, width_px, CV_32S, cv::Scalar(0));
  s.gamma = {1.0};
  return s;
}

int ClusterSegmentation::clusterAt(float x_px, float y_px) const {
  if (labels.empty()) return 0;
  const int col = std::clamp(static_cast<int>(std::lround(x_px)), 0, labels.cols - 1);
  const int row = std::clamp(static_cast<int>(std::lround(y_px)), 0, labels.rows - 1);
  return labels.type() == CV_32S ? labels.at<int>(row, col) : static_cast<int>(labels.at<std::uint16_t>(row, col));
}

double ClusterSegmentation::gammaOf(int cluster) const {
  if (cluster < 0 || cluster >= numClusters()) return 1.0;
  return gamma[static_cast<std::size_t>(cluster)];
}

double ClusterSegmentation::staticAreaRatio(double static_threshold) const {
  if (labels.empty()) return gammaOf(0) >= static_threshold ? 1.0 : 0.0;
  std::vector<bool> is_static(gamma.size());
  for (std::size_t k = 0; k < gamma.size(); ++k) is_static[k] = gamma[k] >= static_threshold;
  std::size_t num_static = 0;
  const bool is32 = labels.type() == CV_32S;
  for (int r = 0; r < labels.rows; ++r) {
    for (int c = 0; c < labels.cols; ++c) {
      const int k = is32 ? labels.at<int>(r, c) : static_cast<int>(labels.at<std::uint16_t>(r, c));
      // Labels outside the score table count as static, as gammaOf() says.
      if (k < 0 || k >= numClusters() || is_static[static_cast<std::size_t>(k)]) ++num_static;
    }
  }
  return static_cast<double>(num_static) / static_cast<double>(labels.total());
}

void ClusterSegmentation::validate() const {
  LTLO_ASSERT(labels.empty() || labels.type() == CV_32S || labels.type() == CV_16U,
              "cluster labels must be CV_32S or CV_16U, got OpenCV type " << labels.type());
  LTLO_ASSERT(!gamma.empty(), "a segmentation needs at least one cluster score");
  for (std::size_t k = 0; k < gamma.size(); ++k) {
    LTLO_ASSERT(std::isfinite(gamma[k]) && gamma[k] >= 0.0 && gamma[k] <= 1.0,
                "gamma[" << k << "] = " << gamma[k] << ", expected a value in [0, 1]");
  }
  if (!labels.empty()) {
    double min_label = 0.0, max_label = 0.0;
    cv::minMaxLoc(labels, &min_label, &max_label);
    LTLO_ASSERT(min_label >= 0 && max_label < numClusters(), "cluster labels span [" << min_label << ", " << max_label
                                                                                     << "] but only " << numClusters()
                                                                                     << " scores are given");
  }
}

}  // namespace ltlo::map
