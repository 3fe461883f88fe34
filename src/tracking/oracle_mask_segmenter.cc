#include "ltlo/tracking/oracle_mask_segmenter.h"

#include <opencv2/imgproc.hpp>

#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"

namespace ltlo::tracking {

SegmentationOutcome OracleMaskSegmenter::segment(map::Frame& frame, const MotionPrior&) {
  LTLO_ASSERT(input_ != nullptr, "OracleMaskSegmenter::segment without begin()");
  const io::RgbdImuFrame& input = *input_;
  input_ = nullptr;
  if (input.mask.empty()) {
    throw InputError(input.color_path, 0,
                     "--oracle-masks: no ground-truth mask for this frame (t = " + std::to_string(input.t_s) +
                         " s; the sequence needs masks/<timestamp>.png for every frame)");
  }
  LTLO_ASSERT(input.mask.type() == CV_8UC1 && input.mask.size() == input.color_bgr.size(),
              "oracle mask of frame " << input.index << " is not an 8-bit image of the colour image's size");
  const bool has_depth = !input.depth_m.empty();
  const cv::Mat* mask_image = &input.mask;
  const cv::Mat* depth_image = &input.depth_m;
  if (undistorter_ && undistorter_->active()) {
    undistorter_->toIdeal(input.mask, &mask_ideal_, cv::INTER_NEAREST);
    mask_image = &mask_ideal_;
    if (has_depth) {
      undistorter_->toIdeal(input.depth_m, &depth_ideal_, cv::INTER_NEAREST);
      depth_image = &depth_ideal_;
    }
  }

  map::ClusterSegmentation seg;
  seg.scale = kLabelScale;
  seg.labels.create(mask_image->rows / kLabelScale, mask_image->cols / kLabelScale, CV_8U);
  seg.gamma = {1.0, 0.0, 1.0};  // static with depth, dynamic, static without depth (cluster K)
  seg.pixel_counts.assign(seg.gamma.size(), 0);
  for (int r = 0; r < seg.labels.rows; ++r) {
    const std::uint8_t* mask = mask_image->ptr<std::uint8_t>(r * kLabelScale);
    const float* depth = has_depth ? depth_image->ptr<float>(r * kLabelScale) : nullptr;
    std::uint8_t* label = seg.labels.ptr<std::uint8_t>(r);
    for (int c = 0; c < seg.labels.cols; ++c) {
      const int u = c * kLabelScale;
      int cluster = kNoDepthCluster;
      if (mask[u] != 0) {
        cluster = kDynamicCluster;
      } else if (depth != nullptr && depth[u] > 0.0f) {
        cluster = kStaticCluster;
      }
      label[c] = static_cast<std::uint8_t>(cluster);
      ++seg.pixel_counts[static_cast<std::size_t>(cluster)];
    }
  }
  if (seg.pixel_counts[kStaticCluster] > 0 && seg.pixel_counts[kDynamicCluster] > 0) {
    seg.neighbours.emplace_back(kStaticCluster, kDynamicCluster);
  }
  if (has_depth) {
    // Nearest-sample decimation to quarter resolution, in mm (0 = no reading; saturates at 65.5 m).
    cv::Mat depth_small;
    cv::resize(*depth_image, depth_small, cv::Size(depth_image->cols / kDepthScale, depth_image->rows / kDepthScale),
               0.0, 0.0, cv::INTER_NEAREST);
    depth_small.convertTo(seg.depth_mm, CV_16U, 1000.0);
    seg.depth_scale = kDepthScale;
  }
  frame.setSegmentation(std::move(seg), static_threshold_);
  SegmentationOutcome outcome;
  const int with_depth = frame.segmentation().pixel_counts[kStaticCluster] + frame.segmentation().pixel_counts[kDynamicCluster];
  outcome.dynamic_share = with_depth > 0 ? static_cast<double>(frame.segmentation().pixel_counts[kDynamicCluster]) / with_depth : 0.0;
  return outcome;
}

}  // namespace ltlo::tracking
