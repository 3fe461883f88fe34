#pragma once
/// OracleMaskSegmenter: the --oracle-masks ablation (diagnostic only). The frame's ground-truth
/// dynamic mask (io::RgbdImuFrame::mask, the sequence's masks/; read only when the reader is asked
/// to) stands in for the segmentation, so the rest of the system can be measured under perfect
/// segmentation: gamma = 0 on every dynamic pixel.
///
/// Layout (map::ClusterSegmentation at half the input resolution, as the depth-cluster
/// segmenters): cluster 0 the static pixels with depth (gamma 1), cluster 1 the dynamic pixels,
/// with or without depth (gamma 0), cluster 2 the static pixels without depth (the no-depth
/// cluster K, gamma 1). Pixel counts, V_i ({0, 1} when both exist: the objects stand on and
/// against the static scene) and depth_mm (quarter resolution) are filled, so local mapping's
/// gamma prior (Eq. 56) and the static-area gate of loop closing work on them. The static area of a
/// frame is its static pixels with depth over those plus all dynamic pixels (a dynamic pixel
/// without depth counts as dynamic area: the gate errs on the safe side).
#include <memory>

#include "ltlo/core/undistorter.h"
#include "ltlo/tracking/frame_segmenter.h"

namespace ltlo::tracking {

/// Not thread-safe: one tracking thread calls begin() and segment() alternately.
class OracleMaskSegmenter final : public FrameSegmenter {
 public:
  /// With an active `undistorter` the raw mask and depth are first remapped onto the ideal grid.
  explicit OracleMaskSegmenter(double static_threshold, std::shared_ptr<const Undistorter> undistorter = nullptr)
      : static_threshold_(static_threshold), undistorter_(std::move(undistorter)) {}
  void begin(const io::RgbdImuFrame& input) override { input_ = &input; }
  /// Throws InputError naming the frame when it has no mask (masks/ missing or not read).
  SegmentationOutcome segment(map::Frame& frame, const MotionPrior& prior) override;
  void cancel() override { input_ = nullptr; }
  const char* name() const override { return "oracle-masks"; }

  /// Label pixels per input pixel along each axis, and depth_mm pixels per input pixel.
  static constexpr int kLabelScale = 2;
  static constexpr int kDepthScale = 4;
  static constexpr int kStaticCluster = 0;
  static constexpr int kDynamicCluster = 1;
  static constexpr int kNoDepthCluster = 2;

 private:
  double static_threshold_;
  std::shared_ptr<const Undistorter> undistorter_;
  const io::RgbdImuFrame* input_ = nullptr;
  cv::Mat mask_ideal_, depth_ideal_;  // reused buffers of the remapped images
};

}  // namespace ltlo::tracking
