// bench_hindsight: one frame of the hindsight masks' free-space test against a growing number of
// keyframe views, bounded (Seg.HindsightFreeSpaceMaxViews 32) and unbounded (0) in the same run; report
// the ratios (the machine's load cancels out).
//
//   BM_HindsightRelabel/views/max_views  HindsightRelabeller::relabel of a VGA frame (label 320x240: a
//                           wall at 3 m, a box at 1 m over a quarter of the view, an all-static online
//                           mask, no map points) against `views` keyframes 0-0.5 m around the frame that
//                           saw the bare wall (the box's samples are seen through, the wall's seen), with
//                           max_views 0 (every view facing the frame) or 32. A long run's revisits are
//                           the many-views case: 438 keyframes after 5 minutes.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include <opencv2/core.hpp>

#include "ltlo/core/camera_model.h"
#include "ltlo/system/hindsight_masks.h"

namespace ltlo::system {
namespace {

constexpr int kWidth = 640, kHeight = 480;

struct Scene {
  CameraModel camera{PinholeCamera(525.0, 525.0, 319.5, 239.5, kWidth, kHeight), LensDistortion()};
  SE3 T_w_c = SE3::exp((Vec6() << 0.1, -0.2, 0.05, 0.1, 0.2, -0.1).finished());
  cv::Mat depth{kHeight, kWidth, CV_32F, cv::Scalar(3.0)};
  cv::Mat wall{kHeight, kWidth, CV_32F, cv::Scalar(3.0)};

  Scene() { depth(cv::Rect(160, 120, 320, 240)).setTo(1.0); }

  /// `count` views of the wall from points on a spiral within 0.5 m of the frame, facing as it does.
  std::vector<FreeSpaceView> views(int count) const {
    std::vector<FreeSpaceView> out;
    for (int k = 0; k < count; ++k) {
      const double radius = 0.5 * std::sqrt((k + 0.5) / count), angle = 2.39996 * k;
      const Vec3 offset_c(radius * std::cos(angle), radius * std::sin(angle), 0.0);
      out.push_back(FreeSpaceView::fromDepth(wall, T_w_c * SE3(Quat::Identity(), offset_c), 1.0 + k, 4));
    }
    return out;
  }
};

void BM_HindsightRelabel(benchmark::State& state) {
  static const Scene scene;
  const std::vector<FreeSpaceView> views = scene.views(static_cast<int>(state.range(0)));
  HindsightMaskOptions options;
  options.free_space_max_views = static_cast<int>(state.range(1));
  HindsightRelabeller relabeller(scene.camera, options);
  const cv::Mat online(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
  cv::Mat mask;
  HindsightFrameResult result;
  for (auto _ : state) {
    online.copyTo(mask);
    result = relabeller.relabel(scene.depth, scene.T_w_c, {}, &mask, views, 0.0);
    benchmark::DoNotOptimize(mask.data);
  }
  state.counters["asked"] = result.views_asked;
  state.counters["flipped"] = result.regions_flipped;
}
BENCHMARK(BM_HindsightRelabel)
    ->ArgNames({"views", "max_views"})
    ->ArgsProduct({{32, 128, 512}, {0, 32}})
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ltlo::system

BENCHMARK_MAIN();
