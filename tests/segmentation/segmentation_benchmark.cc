// bench_segmentation: DepthClustering on a generated 640x480 depth image (K = 24, 320x240 working
// resolution, 3 Lloyd iterations on a quarter of the samples plus a final assignment of all, the
// cut at depth steps and creases, connectivity and full-resolution labels included) against a
// plain cv::kmeans on all the same 320x240 working points (3 iterations, one attempt, random
// centres, one thread like ours). Report the ratio of the two times from the same run; the second
// call onwards reuses DepthClustering's buffers, as in the tracking thread.
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>

#include "ltlo/segmentation/depth_clustering.h"
#include "segmentation/synthetic_depth.h"

namespace ltlo::segmentation {
namespace {

const test::SyntheticDepth& scene() {
  static const test::SyntheticDepth depth = test::makeTwoPlanesAndBox(640, 480);
  return depth;
}

void BM_DepthClustering(benchmark::State& state) {
  DepthClustering clustering(DepthClusteringOptions{});
  for (auto _ : state) {
    ClusterMap clusters = clustering.cluster(scene().depth_m, scene().camera);
    benchmark::DoNotOptimize(clusters.labels.data);
  }
}
BENCHMARK(BM_DepthClustering)->Unit(benchmark::kMillisecond);

void BM_CvKmeansSamePoints(benchmark::State& state) {
  cv::setNumThreads(1);
  const PinholeCamera& camera = scene().camera;
  std::vector<cv::Point3f> points;
  for (int v = 0; v < 480; v += 2) {
    for (int u = 0; u < 640; u += 2) {
      const float z = scene().depth_m.at<float>(v, u);
      if (z <= 0.0f) continue;
      points.emplace_back(static_cast<float>((u - camera.cx()) / camera.fx() * z),
                          static_cast<float>((v - camera.cy()) / camera.fy() * z), z);
    }
  }
  const cv::Mat samples(static_cast<int>(points.size()), 3, CV_32F, points.data());
  for (auto _ : state) {
    cv::theRNG().state = 1;
    cv::Mat labels, centres;
    cv::kmeans(samples, 24, labels, cv::TermCriteria(cv::TermCriteria::COUNT, 3, 0.0), 1,
               cv::KMEANS_RANDOM_CENTERS, centres);
    benchmark::DoNotOptimize(labels.data);
  }
  state.counters["points"] = static_cast<double>(points.size());
}
BENCHMARK(BM_CvKmeansSamePoints)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ltlo::segmentation

BENCHMARK_MAIN();
