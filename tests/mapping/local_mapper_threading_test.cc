// LocalMapper in its own thread (issue 6): keyframes inserted from tracking, pause()/resume() from
// a third thread, requestFinish() + join; every keyframe processed, none while paused, the same
// accuracy as the synchronous run. Meant to run clean under ThreadSanitizer.
#include <gtest/gtest.h>

#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "common/log_capture.h"

#include "ltlo/imu/inertial_residual.h"
#include "ltlo/map/atlas.h"
#include "mapping_test_fixture.h"

namespace ltlo::mapping::test {
namespace {

TEST_F(MappingOnSimulatedSequence, ThreadedMappingWithPausesProcessesEveryKeyFrame) {
  RunConfig config;
  config.options = mapperOptions(/*use_imu=*/true);
  config.threaded = true;
  config.pause_rounds = 10;
  const RunResult result = run(config);
  std::printf("threaded: ATE rmse %.4f m max %.4f m, keyframe ATE %.4f m; keyframes %d (%d processed, %d in "
              "map), BA runs %d, fused %d, culled points %d keyframes %d, pauses %d, IMU estimates %d, "
              "gravity error %.3f deg; per keyframe %.1f ms mean\n",
              result.ate.error_m.rmse, result.ate.error_m.max, result.keyframe_ate.error_m.rmse,
              result.keyframes_created, result.counters.keyframes_processed, result.keyframes_in_map,
              result.counters.local_ba_runs, result.counters.fused_points, result.counters.culled_points,
              result.counters.culled_keyframes, result.pauses, result.counters.imu_initialisations,
              angleDeg(result.imu.g_w, imu::gravityWorld()), result.mapping_mean_ms);
  EXPECT_EQ(result.ok, result.frames);
  EXPECT_EQ(result.counters.keyframes_processed, result.keyframes_created);
  EXPECT_EQ(result.pauses, 10);
  EXPECT_EQ(result.processed_while_paused, 0);
  EXPECT_GT(result.counters.local_ba_runs, 0);
  EXPECT_TRUE(result.imu.initialised);
  EXPECT_LT(angleDeg(result.imu.g_w, imu::gravityWorld()), 1.5);
  EXPECT_LT(result.ate.error_m.rmse, 0.03);
}

TEST(LocalMapperThreads, PauseReturnsAtOnceWithoutRunAndRunEndsAfterFinish) {
  map::Atlas atlas(16);
  LocalMapper mapper(atlas, LocalMapperOptions(), std::vector<float>{1.0f, 1.44f});
  mapper.pause();  // run() is not running: returns at once
  mapper.resume();
  EXPECT_FALSE(mapper.finished());
  mapper.requestFinish();
  std::thread mapping([&] { mapper.run(); });
  mapping.join();
  EXPECT_TRUE(mapper.finished());
  EXPECT_EQ(mapper.counters().keyframes_processed, 0);
  EXPECT_FALSE(mapper.imuState().initialised);
}

TEST(LocalMapperThreads, AnExceptionEndsRunWithTheKeyFrameInTheLog) {
  map::Atlas atlas(16);
  map::Map& map = atlas.activeMap();
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;
  for (int n = 0; n < 2; ++n) {
    map::Frame frame(0.1 * n, PinholeCamera(262.5, 262.5, 159.5, 119.5, 320, 240), SE3(), features::OrbFeatures(),
                     std::vector<float>(), std::vector<float>{1.0f, 1.2f});
    frame.setPose_T_w_b(SE3());
    keyframes.push_back(map.createKeyFrame(frame));
  }
  LocalMapper mapper(atlas, LocalMapperOptions(), std::vector<float>{1.0f, 1.44f});
  mapper.setKeyFrameProcessedCallback([](const std::shared_ptr<map::KeyFrame>&) {
    throw std::runtime_error("loop closing refused it");
  });
  ltlo::test::LogCapture capture(log::Level::kWarn);
  mapper.insertKeyFrame(keyframes[0]);
  std::thread mapping([&] { mapper.run(); });
  mapping.join();
  EXPECT_TRUE(mapper.finished());
  EXPECT_EQ(mapper.counters().keyframes_processed, 1);
  std::ostringstream expected;
  expected << "local mapping failed on keyframe " << keyframes[0]->id() << ": loop closing refused it";
  EXPECT_TRUE(capture.contains(expected.str()));
  mapper.insertKeyFrame(keyframes[1]);  // the queue is closed: refused with a warning, never blocks
  EXPECT_TRUE(capture.contains("not processed"));
  EXPECT_EQ(mapper.queuedKeyFrames(), 0u);
}

}  // namespace
}  // namespace ltlo::mapping::test
