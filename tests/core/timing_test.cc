// TimingStats statistics on fed durations (the clock itself is never asserted on).
#include "ltlo/core/timing.h"

#include <gtest/gtest.h>

#include <string>
#include <thread>
#include <vector>

#include "ltlo/core/assert.h"

namespace ltlo {
namespace {

TEST(Percentile, InterpolatesBetweenOrderStatistics) {
  EXPECT_DOUBLE_EQ(percentile({}, 0.5), 0.0);
  EXPECT_DOUBLE_EQ(percentile({4.0}, 0.95), 4.0);
  EXPECT_DOUBLE_EQ(percentile({3.0, 1.0, 2.0}, 0.5), 2.0);  // unsorted input
  EXPECT_DOUBLE_EQ(percentile({1.0, 2.0, 3.0, 4.0}, 0.5), 2.5);
  EXPECT_DOUBLE_EQ(percentile({1.0, 2.0, 3.0, 4.0}, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(percentile({1.0, 2.0, 3.0, 4.0}, 1.0), 4.0);
  // position 0.95 * 4 = 3.8 between 40 and 50
  EXPECT_DOUBLE_EQ(percentile({10.0, 20.0, 30.0, 40.0, 50.0}, 0.95), 48.0);
}

TEST(TimingStats, SummarisesFedDurations) {
  TimingStats stats;
  // 1..100 ms in a scrambled order: median 50.5 ms, p95 at position 94.05 -> 95.05 ms.
  for (int i = 0; i < 100; ++i)
    stats.add("tracking.orb", 1e-3 * static_cast<double>((i * 37) % 100 + 1));
  stats.add("mapping.ba", 0.25);
  const StageTiming orb = stats.stage("tracking.orb");
  EXPECT_EQ(orb.count, 100u);
  EXPECT_NEAR(orb.total_s, 5.050, 1e-12);
  EXPECT_NEAR(orb.mean_s, 0.0505, 1e-12);
  EXPECT_NEAR(orb.median_s, 0.0505, 1e-12);
  EXPECT_NEAR(orb.p95_s, 0.09505, 1e-12);
  EXPECT_NEAR(orb.max_s, 0.100, 1e-12);

  const std::vector<StageTiming> all = stats.stages();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].stage, "mapping.ba");  // sorted by name
  EXPECT_EQ(all[1].stage, "tracking.orb");
  EXPECT_EQ(stats.stage("never").count, 0u);
  EXPECT_DOUBLE_EQ(stats.stage("never").p95_s, 0.0);

  EXPECT_EQ(stats.summary(),
            "mapping.ba n=1 mean=250.000 median=250.000 p95=250.000 max=250.000 ms\n"
            "tracking.orb n=100 mean=50.500 median=50.500 p95=95.050 max=100.000 ms");
  EXPECT_EQ(
      stats.toJson(),
      "{\"mapping.ba\": {\"count\": 1, \"mean_ms\": 250, \"median_ms\": 250, \"p95_ms\": 250, "
      "\"max_ms\": 250, \"total_s\": 0.25}, \"tracking.orb\": {\"count\": 100, \"mean_ms\": "
      "50.5, \"median_ms\": 50.5, \"p95_ms\": 95.05, \"max_ms\": 100, \"total_s\": 5.05}}");
  stats.clear();
  EXPECT_TRUE(stats.stages().empty());
  EXPECT_EQ(stats.toJson(), "{}");
}

TEST(TimingStats, AccumulatesFromManyThreads) {
  TimingStats stats;
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&stats, t] {
      for (int i = 0; i < 1000; ++i) stats.add(t % 2 == 0 ? "even" : "odd", 1e-3);
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(stats.stage("even").count, 2000u);
  EXPECT_EQ(stats.stage("odd").count, 2000u);
  EXPECT_NEAR(stats.stage("odd").total_s, 2.0, 1e-9);
}

TEST(ScopedTimer, RecordsExactlyOnce) {
  TimingStats stats;
  {
    ScopedTimer timer(stats, "stage");
    const double d = timer.stop();
    EXPECT_GE(d, 0.0);
    EXPECT_DOUBLE_EQ(timer.stop(), 0.0);  // already recorded
  }                                       // destructor after stop(): no second record
  { ScopedTimer timer(stats, "stage"); }
  EXPECT_EQ(stats.stage("stage").count, 2u);
}

#ifndef LTLO_DISABLE_ASSERTS
TEST(TimingStats, RejectsNegativeDuration) {
  TimingStats stats;
  EXPECT_THROW(stats.add("stage", -1.0), AssertionError);
}
#endif

}  // namespace
}  // namespace ltlo
