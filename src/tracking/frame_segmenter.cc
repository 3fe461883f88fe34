#include "ltlo/tracking/frame_segmenter.h"

#include <algorithm>
#include <optional>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "ltlo/tracking/prepared_frame.h"
#include "segmentation_worker.h"

namespace ltlo::tracking {

SegmentationOutcome AllStaticSegmenter::segment(map::Frame& frame, const MotionPrior&) {
  frame.setSegmentation(map::ClusterSegmentation::allStatic(), static_threshold_);
  return {};
}

ClusterOnlySegmenter::ClusterOnlySegmenter(const SegmentationOptions& segmentation, const DenseOptions& dense,
                                           const PinholeCamera& camera, TimingStats* timing,
                                           std::shared_ptr<const Undistorter> undistorter)
    : static_threshold_(segmentation.static_threshold), prepared_(std::make_unique<PreparedFrame>()) {
  segmentation::DenseFrameOptions frame_options = segmentation::DenseFrameOptions::from(segmentation, dense);
  frame_options.num_levels = std::min(2, frame_options.num_levels);  // level 1 holds the depth for Eq. 56
  frame_options.finest_solved_level = frame_options.num_levels;      // no dense solve: images and labels only
  auto kmeans = std::make_shared<segmentation::DepthKMeans>(segmentation::DepthKMeansOptions::from(segmentation));
  worker_ = std::make_unique<SegmentationWorker>([this, frame_options, kmeans, camera, timing, undistorter](
                                                     const io::RgbdImuFrame& input) {
    prepareFrame(input, camera, frame_options, *kmeans, prepared_.get(), timing, undistorter.get());
  });
}

ClusterOnlySegmenter::~ClusterOnlySegmenter() { worker_.reset(); }

void ClusterOnlySegmenter::begin(const io::RgbdImuFrame& input) {
  LTLO_ASSERT(worker_ != nullptr, "ClusterOnlySegmenter::begin after finish()");
  worker_->post(input);
}

void ClusterOnlySegmenter::finish() {
  if (worker_ == nullptr) return;
  cancel();
  worker_.reset();
}

void ClusterOnlySegmenter::cancel() {
  if (worker_ == nullptr) return;  // finished
  try {
    worker_->wait();
  } catch (const std::exception& e) {
    log::warn("clustering of a cancelled frame failed: ", e.what());
  }
}

SegmentationOutcome ClusterOnlySegmenter::segment(map::Frame& frame, const MotionPrior&) {
  LTLO_ASSERT(worker_->pending(), "ClusterOnlySegmenter::segment without begin()");
  worker_->wait();
  if (!prepared_->valid) {
    frame.setSegmentation(map::ClusterSegmentation::allStatic(), static_threshold_);
    return {};
  }
  const std::vector<double> gamma(static_cast<std::size_t>(prepared_->clusters.num_clusters) + 1, 1.0);
  frame.setSegmentation(clusterSegmentation(*prepared_, gamma), static_threshold_);
  return {};
}

}  // namespace ltlo::tracking
