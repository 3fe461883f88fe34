#pragma once
// Shared fixture of the local-mapping tests: one simulated static RGB-D-inertial sequence written
// once per test binary, and a runner feeding it through Tracker + LocalMapper (synchronously in the
// tracking callback, or with the mapper's run() in its own thread and a third thread pausing it).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "ltlo/core/timing.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/mapping/local_mapper.h"

namespace ltlo::mapping::test {

struct RunConfig {
  bool with_mapper = true;
  LocalMapperOptions options;
  bool threaded = false;
  int pause_rounds = 0;  ///< threaded: pause()/resume() cycles from a third thread
};

struct KeyFrameVelocity {
  double t_s = 0.0;
  Vec3 v_w_b = Vec3::Zero();
};

struct RunResult {
  int frames = 0;
  int ok = 0;
  int keyframes_created = 0;
  int keyframes_in_map = 0;
  eval::AteResult ate;           ///< tracked frames (poses at tracking time)
  eval::AteResult keyframe_ate;  ///< final keyframe poses in the map
  LocalMapperCounters counters;
  ImuState imu;
  double imu_initialised_at_s = -1.0;  ///< keyframe time when imuState() first became initialised
  std::vector<KeyFrameVelocity> velocities;  ///< final keyframes of the map
  double mapping_mean_ms = 0.0;
  double mapping_max_ms = 0.0;
  double local_ba_mean_ms = 0.0;
  int pauses = 0;
  int processed_while_paused = 0;
  int points_in_map = 0;
};

class MappingOnSimulatedSequence : public ::testing::Test {
 protected:
  static void SetUpTestSuite();
  static void TearDownTestSuite();
  static RunResult run(const RunConfig& config);
  /// Body velocity in the world from the ground truth (central differences of T_w_b positions).
  static Vec3 trueVelocity(double t_s);
  /// The simulator's true biases (imu_biases.txt) at the sample nearest to t_s.
  static imu::ImuBias trueBias(double t_s);
  /// The options of the tests: the IMU initialised after 6 keyframes (2 s), refined 1.5 and 3 s later.
  static LocalMapperOptions mapperOptions(bool use_imu);
};

/// Angle between two vectors (deg).
double angleDeg(const Vec3& a, const Vec3& b);

}  // namespace ltlo::mapping::test
