#pragma once
/// The mapping timeline of a run (LocalMapper::timeline, mapping_timeline.csv).
#include <cstddef>
#include <cstdint>

namespace ltlo::mapping {

/// One processed keyframe of the mapping timeline (mapping_timeline.csv in the run folder): how the
/// cost of local mapping, the atlas and the memory grow over a long run.
struct MappingTimelineEntry {
  double t_s = 0.0;                 ///< the keyframe's timestamp (sequence time, s)
  std::uint64_t keyframe_id = 0;
  double mapping_ms = 0.0;          ///< its whole processing (the "mapping.keyframe" stage)
  std::size_t atlas_keyframes = 0;  ///< keyframes in all maps after it
  std::size_t atlas_map_points = 0;
  double resident_mb = 0.0;         ///< resident set size of the process after it
  /// Its local BA's problem size (all 0 when it ran none): a measure of the mapping cost that,
  /// unlike mapping_ms, does not depend on the machine's load (issue 32).
  int ba_optimised_keyframes = 0;
  int ba_fixed_keyframes = 0;
  int ba_points = 0;
  int ba_observations = 0;
  int ba_fixed_observations = 0;       ///< of ba_observations, those by fixed keyframes
  int ba_fixed_observation_limit = 0;  ///< the per-point limit on them applied (0: none)
  int ba_probe_points = 0;             ///< points of the fixed keyframes projected for Eq. 56
  int ba_iterations = 0;               ///< the optimiser's, over all rounds
  /// Where mapping_ms went (ms): point culling and fusion, local BA, keyframe culling, and the IMU
  /// steps (initialisation, refinement, time offset). The rest is bookkeeping.
  double points_ms = 0.0;
  double ba_ms = 0.0;
  double keyframe_culling_ms = 0.0;
  double imu_ms = 0.0;
  /// The mapping thread's CPU time for the keyframe (ms, CLOCK_THREAD_CPUTIME_ID): its work alone.
  /// mapping_ms is wall time and also counts the waits for the cores, which the loop closer's
  /// global BA and the other threads take on a 2-core machine.
  double mapping_cpu_ms = 0.0;
};

}  // namespace ltlo::mapping
