#pragma once
/// Vision-only full bundle adjustment of a map after a loop (namespace ltlo::loop), through
/// optim::localBundleAdjust with every keyframe and point. The loop-closing thread runs it in its own
/// thread (system/); this function works on a snapshot and writes the results back.
#include <atomic>

#include "ltlo/map/map.h"

namespace ltlo::loop {

struct GlobalBaOptions {
  int iterations = 10;  ///< Loop.FullBaIterations
  /// Virtual stereo baseline of the RGB-D edges (bf = fx * baseline), m.
  double virtual_baseline_m = 0.08;
  int num_threads = 2;
  const std::atomic<bool>* stop_flag = nullptr;  ///< a new loop aborts the BA
};

struct GlobalBaResult {
  int keyframes = 0;
  int points = 0;
  int observations = 0;
  int outliers = 0;  ///< observations failing the chi2 test at the end (left linked)
  double initial_chi2 = 0.0;
  double final_chi2 = 0.0;
};

/// Optimises every good keyframe's T_w_b and every point seen by >= 2 of them; the map's origin
/// keyframes are fixed (gauge). Keyframes and points created during the run are not moved (ORB-SLAM
/// propagates the correction to them through the spanning tree; not done yet). Uses the first
/// keyframe's camera and T_b_c for all.
GlobalBaResult runGlobalBundleAdjustment(map::Map& map, const GlobalBaOptions& options = GlobalBaOptions());

}  // namespace ltlo::loop
