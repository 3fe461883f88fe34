// bench_grid: the keypoint grid of search by projection (map::GridIndex, one flat array of cells),
// built once per frame and asked ~1000 windows per frame, against the layout it replaced (a vector per
// cell) in the same process. Compare the "real_time" of each pair; the ratios are printed last as
// "build ratio=<flat/nested>" and "query ratio=<flat/nested>".
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "ltlo/map/grid_index.h"

namespace {

using ltlo::features::Keypoint;
constexpr int kWidth = 640, kHeight = 480, kKeypoints = 1500, kQueries = 1000;
constexpr float kCell = 16.0f, kRadius = 15.0f;

/// Keypoints spread as ORB spreads them: uniform over the image, octaves 0-7.
const std::vector<Keypoint>& keypoints() {
  static const std::vector<Keypoint> kps = [] {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> x(0.0f, kWidth - 1.0f), y(0.0f, kHeight - 1.0f);
    std::uniform_int_distribution<int> octave(0, 7);
    std::vector<Keypoint> out(kKeypoints);
    for (Keypoint& kp : out) {
      kp.x_px = x(rng);
      kp.y_px = y(rng);
      kp.octave = octave(rng);
    }
    return out;
  }();
  return kps;
}

const std::vector<std::pair<float, float>>& queries() {
  static const std::vector<std::pair<float, float>> q = [] {
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> x(0.0f, kWidth - 1.0f), y(0.0f, kHeight - 1.0f);
    std::vector<std::pair<float, float>> out(kQueries);
    for (auto& p : out) p = {x(rng), y(rng)};
    return out;
  }();
  return q;
}

/// The layout GridIndex had before: a vector of indices per cell.
class NestedGrid {
 public:
  NestedGrid(const std::vector<Keypoint>& kps, int width_px, int height_px, float cell_px)
      : cols_(static_cast<int>(std::ceil(width_px / cell_px))),
        rows_(static_cast<int>(std::ceil(height_px / cell_px))),
        inv_cell_(1.0f / cell_px),
        cells_(static_cast<std::size_t>(cols_ * rows_)) {
    for (std::size_t i = 0; i < kps.size(); ++i) {
      const int col = std::clamp(static_cast<int>(kps[i].x_px * inv_cell_), 0, cols_ - 1);
      const int row = std::clamp(static_cast<int>(kps[i].y_px * inv_cell_), 0, rows_ - 1);
      cells_[static_cast<std::size_t>(row * cols_ + col)].push_back(static_cast<int>(i));
    }
  }
  void featuresInArea(const std::vector<Keypoint>& kps, float x_px, float y_px, float r, std::vector<int>* found) const {
    found->clear();
    const int col_min = std::max(0, static_cast<int>(std::floor((x_px - r) * inv_cell_)));
    const int col_max = std::min(cols_ - 1, static_cast<int>(std::floor((x_px + r) * inv_cell_)));
    const int row_min = std::max(0, static_cast<int>(std::floor((y_px - r) * inv_cell_)));
    const int row_max = std::min(rows_ - 1, static_cast<int>(std::floor((y_px + r) * inv_cell_)));
    for (int row = row_min; row <= row_max; ++row) {
      for (int col = col_min; col <= col_max; ++col) {
        for (int i : cells_[static_cast<std::size_t>(row * cols_ + col)]) {
          const Keypoint& kp = kps[static_cast<std::size_t>(i)];
          if (std::abs(kp.x_px - x_px) > r || std::abs(kp.y_px - y_px) > r) continue;
          found->push_back(i);
        }
      }
    }
    std::sort(found->begin(), found->end());
  }

 private:
  int cols_, rows_;
  float inv_cell_;
  std::vector<std::vector<int>> cells_;
};

void BM_GridBuildFlat(benchmark::State& state) {
  for (auto _ : state) {
    ltlo::map::GridIndex grid(keypoints(), kWidth, kHeight, kCell);
    benchmark::DoNotOptimize(&grid);
  }
}
BENCHMARK(BM_GridBuildFlat)->Unit(benchmark::kMicrosecond)->Repetitions(5)->ReportAggregatesOnly(true);

void BM_GridBuildNested(benchmark::State& state) {
  for (auto _ : state) {
    NestedGrid grid(keypoints(), kWidth, kHeight, kCell);
    benchmark::DoNotOptimize(&grid);
  }
}
BENCHMARK(BM_GridBuildNested)->Unit(benchmark::kMicrosecond)->Repetitions(5)->ReportAggregatesOnly(true);

void BM_GridQueriesFlat(benchmark::State& state) {
  const ltlo::map::GridIndex grid(keypoints(), kWidth, kHeight, kCell);
  std::vector<int> found;
  std::size_t total = 0;
  for (auto _ : state) {
    for (const auto& [x, y] : queries()) {
      grid.featuresInArea(keypoints(), x, y, kRadius, 0, -1, &found);
      total += found.size();
    }
  }
  benchmark::DoNotOptimize(total);
}
BENCHMARK(BM_GridQueriesFlat)->Unit(benchmark::kMicrosecond)->Repetitions(5)->ReportAggregatesOnly(true);

void BM_GridQueriesNested(benchmark::State& state) {
  const NestedGrid grid(keypoints(), kWidth, kHeight, kCell);
  std::vector<int> found;
  std::size_t total = 0;
  for (auto _ : state) {
    for (const auto& [x, y] : queries()) {
      grid.featuresInArea(keypoints(), x, y, kRadius, &found);
      total += found.size();
    }
  }
  benchmark::DoNotOptimize(total);
}
BENCHMARK(BM_GridQueriesNested)->Unit(benchmark::kMicrosecond)->Repetitions(5)->ReportAggregatesOnly(true);

/// Median real time of `name`'s repetitions, from the runs the reporter saw.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs) {
      if (run.aggregate_name == "median") medians_[run.run_name.function_name] = run.GetAdjustedRealTime();
    }
    ConsoleReporter::ReportRuns(runs);
  }
  void print() const {
    const auto ratio = [&](const char* a, const char* b) {
      const auto ia = medians_.find(a), ib = medians_.find(b);
      return ia != medians_.end() && ib != medians_.end() && ib->second > 0.0 ? ia->second / ib->second : 0.0;
    };
    std::printf("build ratio=%.3f\nquery ratio=%.3f\n", ratio("BM_GridBuildFlat", "BM_GridBuildNested"),
                ratio("BM_GridQueriesFlat", "BM_GridQueriesNested"));
  }

 private:
  std::map<std::string, double> medians_;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  reporter.print();
  return 0;
}
