// bench_rounds: a robust BA's rounds, three optimize() calls on one graph with new edge weights
// between them (as local mapping's state <-> score alternations). The first call builds the block
// structure; the next two reuse it. Counters: setup time of the first call and of the reused ones
// (same run), and their ratio.
#include <benchmark/benchmark.h>

#include "synthetic_problems.h"

namespace sparse_opt {
namespace {

void BM_ThreeRounds(benchmark::State& state) {
  const int cameras = static_cast<int>(state.range(0));
  const int points = static_cast<int>(state.range(1));
  const testing::BaProblem problem = testing::makeBa(cameras, points, 8, 0.5, 11);
  Options options;
  options.max_iterations = 2;
  double first_setup_s = 0.0, reused_setup_s = 0.0;
  long rounds = 0;
  for (auto _ : state) {
    state.PauseTiming();
    Graph graph;
    testing::buildBaGraph(problem, graph, 1.0);
    state.ResumeTiming();
    for (int round = 0; round < 3; ++round) {
      const Summary summary = graph.optimize(options);
      (round == 0 ? first_setup_s : reused_setup_s) += summary.stage_times.setup_s;
      benchmark::DoNotOptimize(summary.final_chi2);
    }
    ++rounds;
  }
  state.counters["first_setup_ms"] = 1e3 * first_setup_s / rounds;
  state.counters["reused_setup_ms"] = 1e3 * reused_setup_s / (2.0 * rounds);
  state.counters["reused_to_first"] = first_setup_s > 0.0 ? reused_setup_s / (2.0 * first_setup_s) : 0.0;
}
// A local BA window's size (10 optimised keyframes, ~1500 points) and a larger one.
BENCHMARK(BM_ThreeRounds)->Args({10, 1500})->Args({30, 4000})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace sparse_opt

BENCHMARK_MAIN();
