// bench_features: ORB extraction per VGA frame, ours against cv::ORB with the same feature count,
// pyramid and FAST threshold in the same process. Compare the two "real_time" medians; the ratio
// is printed last as "ratio=<ours/opencv>".
#include <algorithm>
#include <chrono>
#include <cstdio>

#include <benchmark/benchmark.h>
#include <opencv2/features2d.hpp>

#include "ltlo/features/orb_extractor.h"
#include "test_images.h"

namespace {

const cv::Mat& frame() {
  static const cv::Mat image = ltlo::features::test::texturedVgaImage();
  return image;
}

void BM_OrbExtractLtlo(benchmark::State& state) {
  const ltlo::features::OrbExtractor extractor{ltlo::features::OrbOptions{}};
  std::size_t n = 0;
  for (auto _ : state) {
    const ltlo::features::OrbFeatures f = extractor.extract(frame());
    n = f.keypoints.size();
    benchmark::DoNotOptimize(f.descriptors.data());
  }
  state.counters["features"] = static_cast<double>(n);
}
BENCHMARK(BM_OrbExtractLtlo)->Unit(benchmark::kMillisecond)->Repetitions(5)->ReportAggregatesOnly(true);

void BM_OrbExtractOpenCv(benchmark::State& state) {
  cv::Ptr<cv::ORB> orb = cv::ORB::create(1000, 1.2f, 8, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31, 20);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  for (auto _ : state) {
    orb->detectAndCompute(frame(), cv::noArray(), keypoints, descriptors);
    benchmark::DoNotOptimize(descriptors.data);
  }
  state.counters["features"] = static_cast<double>(keypoints.size());
}
BENCHMARK(BM_OrbExtractOpenCv)->Unit(benchmark::kMillisecond)->Repetitions(5)->ReportAggregatesOnly(true);

/// Median of `runs` timed calls, milliseconds (for the ratio line).
template <typename F>
double medianMs(F&& f, int runs) {
  std::vector<double> times;
  for (int i = 0; i < runs; ++i) {
    const auto start = std::chrono::steady_clock::now();
    f();
    times.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  }
  std::nth_element(times.begin(), times.begin() + runs / 2, times.end());
  return times[runs / 2];
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (frame().empty()) {
    std::fprintf(stderr, "no wallpaper photograph installed (see scripts/setup.sh)\n");
    return 2;
  }
  cv::setNumThreads(1);  // same footing: both single-threaded
  benchmark::RunSpecifiedBenchmarks();
  // Interleaved medians so that machine load affects both sides alike.
  const ltlo::features::OrbExtractor ours{ltlo::features::OrbOptions{}};
  cv::Ptr<cv::ORB> opencv = cv::ORB::create(1000, 1.2f, 8, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31, 20);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  std::vector<double> ours_ms, opencv_ms;
  for (int round = 0; round < 20; ++round) {
    ours_ms.push_back(medianMs([&] { benchmark::DoNotOptimize(ours.extract(frame()).keypoints.size()); }, 5));
    opencv_ms.push_back(medianMs([&] { opencv->detectAndCompute(frame(), cv::noArray(), keypoints, descriptors); }, 5));
  }
  std::sort(ours_ms.begin(), ours_ms.end());
  std::sort(opencv_ms.begin(), opencv_ms.end());
  const double ours_median = ours_ms[ours_ms.size() / 2];
  const double opencv_median = opencv_ms[opencv_ms.size() / 2];
  std::printf("orb_extraction_vga ours_ms=%.2f opencv_ms=%.2f ratio=%.2f\n", ours_median, opencv_median,
              ours_median / opencv_median);
  return 0;
}
