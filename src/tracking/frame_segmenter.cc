#include "ltlo/tracking/frame_segmenter.h"

#include <algorithm>

#include "ltlo/core/assert.h"
#include "ltlo/segmentation/depth_clustering.h"

namespace ltlo::tracking {

namespace {

/// Label resolution of the segmentation: input px per label px (QVGA labels for VGA input).
constexpr int kLabelScale = 2;
/// Resolution of the depth kept for Eq. 56: input px per depth px (QQVGA for VGA input).
constexpr int kDepthScale = 4;

/// The depth image at 1/scale resolution in mm (the first valid pixel of each block), CV_16U.
cv::Mat depthMillimetres(const cv::Mat& depth_m, int scale) {
  cv::Mat out(depth_m.rows / scale, depth_m.cols / scale, CV_16U, cv::Scalar(0));
  for (int r = 0; r < out.rows; ++r) {
    std::uint16_t* dst = out.ptr<std::uint16_t>(r);
    const float* src = depth_m.ptr<float>(r * scale);
    for (int c = 0; c < out.cols; ++c) {
      const float d = src[c * scale];
      dst[c] = d > 0.0f && d < 65.0f ? static_cast<std::uint16_t>(d * 1000.0f + 0.5f) : 0;
    }
  }
  return out;
}

}  // namespace

SegmentationOutcome AllStaticSegmenter::segment(map::Frame& frame, const MotionPrior&) {
  frame.setSegmentation(map::ClusterSegmentation::allStatic(), static_threshold_);
  return {};
}

ClusterOnlySegmenter::ClusterOnlySegmenter(const SegmentationOptions& segmentation, const DenseOptions& dense,
                                           const PinholeCamera& camera)
    : static_threshold_(segmentation.static_threshold),
      camera_(camera),
      clustering_(std::make_unique<segmentation::DepthClustering>(
          segmentation::DepthClusteringOptions::from(segmentation, dense))) {}

ClusterOnlySegmenter::~ClusterOnlySegmenter() = default;

void ClusterOnlySegmenter::begin(const io::RgbdImuFrame& input) { input_ = &input; }

SegmentationOutcome ClusterOnlySegmenter::segment(map::Frame& frame, const MotionPrior&) {
  LTLO_ASSERT(input_ != nullptr, "ClusterOnlySegmenter::segment without begin()");
  const io::RgbdImuFrame& input = *input_;
  input_ = nullptr;
  if (input.depth_m.empty()) {
    frame.setSegmentation(map::ClusterSegmentation::allStatic(), static_threshold_);
    return {};
  }
  const segmentation::ClusterMap clusters = clustering_->cluster(input.depth_m, camera_);
  map::ClusterSegmentation seg;
  seg.scale = kLabelScale;
  seg.labels.create(clusters.labels.rows / kLabelScale, clusters.labels.cols / kLabelScale, CV_8U);
  seg.gamma.assign(static_cast<std::size_t>(clusters.num_clusters) + 1, 1.0);
  seg.pixel_counts.assign(seg.gamma.size(), 0);
  for (int r = 0; r < seg.labels.rows; ++r) {
    const int* src = clusters.labels.ptr<int>(r * kLabelScale);
    std::uint8_t* dst = seg.labels.ptr<std::uint8_t>(r);
    for (int c = 0; c < seg.labels.cols; ++c) {
      const int label = src[c * kLabelScale];
      dst[c] = static_cast<std::uint8_t>(label);
      ++seg.pixel_counts[static_cast<std::size_t>(label)];
    }
  }
  for (const segmentation::ClusterEdge& edge : clusters.edges) seg.neighbours.emplace_back(edge.a, edge.b);
  seg.depth_scale = kDepthScale;
  seg.depth_mm = depthMillimetres(input.depth_m, kDepthScale);
  frame.setSegmentation(std::move(seg), static_threshold_);
  return {};
}

}  // namespace ltlo::tracking
