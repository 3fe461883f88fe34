#pragma once
/// Vision-only full bundle adjustment of a map after a loop (namespace ltlo::loop), through
/// optim::localBundleAdjust with every keyframe and point. The loop-closing thread runs it in its own
/// thread (system/); this function works on a snapshot and writes the results back.
#include <atomic>
#include <memory>
#include <vector>

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

/// The optimised state of a full BA, not yet written to the map: the snapshot's keyframes and points
/// with their poses/positions at snapshot time and after the optimisation.
struct GlobalBaSolution {
  GlobalBaResult result;
  bool valid = false;  ///< false: nothing to apply (too small, aborted)
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;
  std::vector<SE3> T_w_b_before;  ///< at snapshot time
  std::vector<SE3> T_w_b_after;
  std::vector<std::shared_ptr<map::MapPoint>> points;
  std::vector<Vec3> p_w_after;
};

/// The optimisation part of runGlobalBundleAdjustment on a snapshot of `map` (reads the map only;
/// local mapping may run meanwhile). Invalid when aborted through options.stop_flag.
GlobalBaSolution optimizeGlobalBundleAdjustment(const map::Map& map, const GlobalBaOptions& options = GlobalBaOptions());

/// Writes `solution` into `map` and bumps its version. Keyframes of the snapshot take their optimised
/// pose; keyframes created since (not in the snapshot) move with the correction
/// T_w_b_after * T_w_b_before^-1 of their nearest spanning-tree ancestor in the snapshot (ORB-SLAM's
/// propagation); points not optimised move with their reference keyframe's correction. Call with
/// local mapping paused (it writes poses and points local BA also writes). Returns the number of
/// keyframes moved by propagation.
int applyGlobalBundleAdjustment(map::Map& map, const GlobalBaSolution& solution);

/// Optimises every good keyframe's T_w_b and every point seen by >= 2 of them; the map's origin
/// keyframes are fixed (gauge). optimizeGlobalBundleAdjustment then applyGlobalBundleAdjustment (the
/// loop closer pauses local mapping between the two). Uses the first keyframe's camera and T_b_c for all.
GlobalBaResult runGlobalBundleAdjustment(map::Map& map, const GlobalBaOptions& options = GlobalBaOptions());

}  // namespace ltlo::loop
