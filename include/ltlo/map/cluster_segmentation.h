#pragma once
/// The segmentation seam (DESIGN.md, "Static scores are stored where they are used"): a cluster
/// label image and one static score gamma per cluster, carried by every Frame and KeyFrame.
/// Until the segmentation issue lands, labels come from a trivial segmenter and every gamma is 1.
#include <vector>

#include <opencv2/core.hpp>

namespace ltlo::map {

/// Cluster labels of one image and their static scores Gamma = {gamma_0 .. gamma_K}.
/// Labels are in [0, K]: 0..K-1 are depth clusters, K is the "no depth" cluster (gamma_K = 1).
/// A plain value type; not synchronised (KeyFrame guards its copy with its own mutex).
struct ClusterSegmentation {
  cv::Mat labels;             ///< CV_32S or CV_16U, image size; empty = one cluster over the image
  std::vector<double> gamma;  ///< static score per cluster in [0, 1]; gamma.size() = K + 1

  /// One cluster covering a width x height image with gamma = 1 (the trivially static seam).
  static ClusterSegmentation allStatic(int width_px, int height_px);

  int numClusters() const { return static_cast<int>(gamma.size()); }
  /// Label at pixel (x_px, y_px) (rounded, clamped to the image); 0 when labels is empty.
  int clusterAt(float x_px, float y_px) const;
  /// gamma of `cluster`; 1 for a cluster outside [0, numClusters()) (no evidence of motion).
  double gammaOf(int cluster) const;
  /// Share of labelled pixels whose cluster has gamma >= static_threshold, in [0, 1]
  /// (Loop.MinStaticRatio compares against it). 1 when labels is empty and gamma[0] passes.
  double staticAreaRatio(double static_threshold) const;
  /// LTLO_ASSERTs the label type (CV_32S/CV_16U), labels in [0, numClusters()), gamma in [0, 1].
  void validate() const;
};

}  // namespace ltlo::map
