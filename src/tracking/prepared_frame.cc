#include "ltlo/tracking/prepared_frame.h"

#include <cstdint>
#include <optional>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "ltlo/core/assert.h"

namespace ltlo::tracking {

void prepareFrame(const io::RgbdImuFrame& input, const PinholeCamera& camera,
                  const segmentation::DenseFrameOptions& options, segmentation::DepthKMeans& kmeans,
                  PreparedFrame* out, TimingStats* timing, const Undistorter* undistorter) {
  out->t_s = input.t_s;
  out->valid = !input.color_bgr.empty() && !input.depth_m.empty();
  if (!out->valid) return;
  const cv::Mat* color = &input.color_bgr;
  const cv::Mat* depth = &input.depth_m;
  if (undistorter != nullptr && undistorter->active()) {
    std::optional<ScopedTimer> wall;
    if (timing != nullptr) wall.emplace(*timing, "tracking.undistort");
    // Grey first: one channel to remap instead of three. Intensity bilinear, depth nearest (a depth
    // is a surface's, never a blend across an edge).
    if (input.color_bgr.channels() == 3) {
      cv::cvtColor(input.color_bgr, out->gray_raw, cv::COLOR_BGR2GRAY);
      undistorter->toIdeal(out->gray_raw, &out->gray_ideal, cv::INTER_LINEAR);
    } else {
      undistorter->toIdeal(input.color_bgr, &out->gray_ideal, cv::INTER_LINEAR);
    }
    undistorter->toIdeal(input.depth_m, &out->depth_ideal, cv::INTER_NEAREST);
    color = &out->gray_ideal;
    depth = &out->depth_ideal;
  }
  {
    std::optional<ScopedTimer> wall;
    std::optional<ScopedThreadCpuTimer> cpu;
    if (timing != nullptr) {
      wall.emplace(*timing, "tracking.pyramid");
      cpu.emplace(*timing, "tracking.pyramid_cpu");
    }
    out->dense.build(*color, *depth, camera, options);
  }
  {
    std::optional<ScopedTimer> wall;
    std::optional<ScopedThreadCpuTimer> cpu;
    if (timing != nullptr) {
      wall.emplace(*timing, "tracking.segmentation");
      cpu.emplace(*timing, "tracking.segmentation_cpu");
    }
    const segmentation::DenseLevel& base = out->dense.level(0);
    const PinholeCamera base_camera(base.camera.fx, base.camera.fy, base.camera.cx, base.camera.cy,
                                    base.camera.width, base.camera.height);
    kmeans.cluster(base.depth_m, base_camera, &out->clusters);
  }
  out->dense.setLabels(out->clusters.labels, out->clusters.num_clusters);
}

map::ClusterSegmentation clusterSegmentation(const PreparedFrame& prepared, std::vector<double> gamma) {
  LTLO_ASSERT(prepared.valid, "clusterSegmentation of a frame that was not prepared");
  const segmentation::DepthClusters& clusters = prepared.clusters;
  LTLO_ASSERT(static_cast<int>(gamma.size()) == clusters.num_clusters + 1,
              gamma.size() << " scores for " << clusters.num_clusters << " clusters");
  map::ClusterSegmentation seg;
  seg.labels = clusters.labels.clone();
  seg.scale = prepared.dense.scale();
  seg.gamma = std::move(gamma);
  seg.pixel_counts = clusters.pixel_counts;
  seg.neighbours.reserve(clusters.edges.size());
  for (const segmentation::ClusterEdge& edge : clusters.edges) seg.neighbours.emplace_back(edge.a, edge.b);
  const int depth_level = prepared.dense.numLevels() > 1 ? 1 : 0;
  const cv::Mat& depth_m = prepared.dense.level(depth_level).depth_m;
  seg.depth_scale = prepared.dense.scale() << depth_level;
  seg.depth_mm.create(depth_m.rows, depth_m.cols, CV_16U);
  for (int r = 0; r < depth_m.rows; ++r) {
    const float* src = depth_m.ptr<float>(r);
    std::uint16_t* dst = seg.depth_mm.ptr<std::uint16_t>(r);
    for (int c = 0; c < depth_m.cols; ++c) {
      const float d = src[c];
      dst[c] = d > 0.0f && d < 65.0f ? static_cast<std::uint16_t>(d * 1000.0f + 0.5f) : 0;
    }
  }
  return seg;
}

}  // namespace ltlo::tracking
