#pragma once
// What the segmenters' worker thread prepares from one input frame while the tracking thread
// extracts ORB features: the dense pyramid (DenseFrame) and the depth clusters of its base level.
#include <vector>

#include "ltlo/core/camera.h"
#include "ltlo/core/timing.h"
#include "ltlo/core/undistorter.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/map/cluster_segmentation.h"
#include "ltlo/segmentation/dense_frame.h"
#include "ltlo/segmentation/depth_kmeans.h"

namespace ltlo::tracking {

struct PreparedFrame {
  segmentation::DenseFrame dense;
  segmentation::DepthClusters clusters;
  double t_s = 0.0;
  /// false: the input had no colour or depth image (nothing was built; the frame is one static
  /// cluster)
  bool valid = false;
  /// With a distorting lens: the input's grey and depth images on the ideal pinhole grid (buffers
  /// reused from frame to frame).
  cv::Mat gray_raw, gray_ideal, depth_ideal;
};

/// Builds the pyramid of `input` and clusters its base level (worker thread). With `timing`, the
/// pyramid goes to "tracking.pyramid" and the clustering to "tracking.segmentation" (wall and
/// thread CPU time, "..._cpu"). With an active `undistorter` the grey and depth images are first
/// remapped onto the ideal grid of `camera` ("tracking.undistort"), so the pyramid, the clusters and
/// their labels are those of an ideal pinhole image, where the frame's keypoints are.
void prepareFrame(const io::RgbdImuFrame& input, const PinholeCamera& camera,
                  const segmentation::DenseFrameOptions& options, segmentation::DepthKMeans& kmeans,
                  PreparedFrame* out, TimingStats* timing = nullptr, const Undistorter* undistorter = nullptr);

/// The frame's ClusterSegmentation with scores `gamma` (K + 1): 8-bit labels at the pyramid base
/// (scale = input px per base px), pixel counts, V_i and the depth of pyramid level 1 in mm for
/// Eq. 56 (level 0 when there is a single level). New images: frames and keyframes keep them.
map::ClusterSegmentation clusterSegmentation(const PreparedFrame& prepared, std::vector<double> gamma);

}  // namespace ltlo::tracking
