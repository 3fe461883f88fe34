#include "ltlo/map/cluster_segmentation.h"

#include <algorithm>
#include <cmath>

#include "ltlo/core/assert.h"

namespace ltlo::map {

ClusterSegmentation ClusterSegmentation::allStatic() {
  ClusterSegmentation s;
  s.gamma = {1.0};
  return s;
}

double ClusterSegmentation::gammaOf(int cluster) const {
  if (cluster < 0 || cluster >= numClusters()) return 1.0;
  return gamma[static_cast<std::size_t>(cluster)];
}

double ClusterSegmentation::staticAreaRatio(double static_threshold) const {
  if (labels.empty()) return gammaOf(0) >= static_threshold ? 1.0 : 0.0;
  std::vector<long> counts;
  if (static_cast<int>(pixel_counts.size()) == numClusters()) {
    counts.assign(pixel_counts.begin(), pixel_counts.end());
  } else {
    counts.assign(gamma.size(), 0);
    for (int r = 0; r < labels.rows; ++r) {
      const std::uint8_t* row = labels.ptr<std::uint8_t>(r);
      for (int c = 0; c < labels.cols; ++c) {
        if (row[c] < counts.size()) ++counts[row[c]];
      }
    }
  }
  const int no_depth = noDepthCluster();
  long with_depth = 0, num_static = 0;
  for (int k = 0; k < numClusters(); ++k) {
    if (k == no_depth) continue;
    with_depth += counts[static_cast<std::size_t>(k)];
    if (gamma[static_cast<std::size_t>(k)] >= static_threshold) num_static += counts[static_cast<std::size_t>(k)];
  }
  return with_depth > 0 ? static_cast<double>(num_static) / static_cast<double>(with_depth) : 0.0;
}

cv::Mat ClusterSegmentation::dynamicMask(double static_threshold, int rows, int cols) const {
  if (labels.empty()) {
    LTLO_ASSERT(rows > 0 && cols > 0, "dynamicMask of a label-free segmentation needs the image size");
    return cv::Mat(rows, cols, CV_8U, cv::Scalar(gammaOf(0) >= static_threshold ? 0 : 255));
  }
  cv::Mat lut(1, 256, CV_8U, cv::Scalar(0));
  for (int k = 0; k < numClusters(); ++k) lut.at<std::uint8_t>(0, k) = gamma[static_cast<std::size_t>(k)] >= static_threshold ? 0 : 255;
  cv::Mat mask;
  cv::LUT(labels, lut, mask);
  return mask;
}

std::size_t ClusterSegmentation::memoryBytes() const {
  return labels.total() * labels.elemSize() + depth_mm.total() * depth_mm.elemSize() +
         gamma.size() * sizeof(double) + pixel_counts.size() * sizeof(int) +
         neighbours.size() * sizeof(std::pair<int, int>);
}

void ClusterSegmentation::validate() const {
  LTLO_ASSERT(!gamma.empty(), "a segmentation needs at least one cluster score");
  LTLO_ASSERT(gamma.size() <= 256, "at most 256 clusters fit 8-bit labels, got " << gamma.size());
  LTLO_ASSERT(scale >= 1 && depth_scale >= 1, "segmentation scales must be >= 1, got " << scale << " and " << depth_scale);
  LTLO_ASSERT(labels.empty() || labels.type() == CV_8U, "cluster labels must be CV_8U, got OpenCV type " << labels.type());
  LTLO_ASSERT(depth_mm.empty() || depth_mm.type() == CV_16U, "segmentation depth must be CV_16U mm, got OpenCV type "
                                                                 << depth_mm.type());
  for (std::size_t k = 0; k < gamma.size(); ++k) {
    LTLO_ASSERT(std::isfinite(gamma[k]) && gamma[k] >= 0.0 && gamma[k] <= 1.0,
                "gamma[" << k << "] = " << gamma[k] << ", expected a value in [0, 1]");
  }
  LTLO_ASSERT(pixel_counts.empty() || pixel_counts.size() == gamma.size(),
              pixel_counts.size() << " pixel counts for " << gamma.size() << " clusters");
  for (const auto& [a, b] : neighbours) {
    LTLO_ASSERT(a >= 0 && a < b && b < numClusters(), "neighbour pair (" << a << ", " << b << ") out of range for "
                                                                         << numClusters() << " clusters");
  }
  if (!labels.empty()) {
    double min_label = 0.0, max_label = 0.0;
    cv::minMaxLoc(labels, &min_label, &max_label);
    LTLO_ASSERT(max_label < numClusters(), "cluster labels span [" << min_label << ", " << max_label << "] but only "
                                                                   << numClusters() << " scores are given");
  }
}

}  // namespace ltlo::map
