#pragma once
/// Map merging (namespace ltlo::loop): when a keyframe of the active map recognises a place of
/// another Atlas map, align the two by the same 3-D-3-D RANSAC as a loop, move the active map into
/// the other's frame (Atlas::mergeMaps) and close the loop across the seam (fusion, loop edge,
/// essential graph). Once the IMU is initialised both maps share the run's gravity-aligned world
/// (a new map starts at the predicted pose), so the alignment keeps gravity: yaw about it and
/// translation only (4 DoF); a visual-inertial welding BA then joins the seam.
#include <optional>

#include "ltlo/core/settings.h"
#include "ltlo/loop/loop_corrector.h"
#include "ltlo/map/atlas.h"

namespace ltlo::loop {

struct MergeOptions {
  /// Gravity in the world of both maps (m/s^2) once the IMU is initialised: 4-DoF alignment and
  /// essential graph, velocities turned, then the welding BA. nullopt: SE3 alignment, no welding
  /// BA (the full BA after the merge joins the maps).
  std::optional<Vec3> g_w;
  /// Welding window: the current keyframe and its predecessors in time, and the recognised
  /// keyframe with its neighbours in time, this many on each side (ORB-SLAM3's merge window).
  int welding_keyframes = 10;
  int welding_iterations = 10;      ///< per pass of the welding BA (two passes)
  std::size_t welding_fixed_observers = 30;  ///< other keyframes seeing the window's points, held
  double bf_px_m = 40.0;            ///< RGB-D edges of the welding BA
  double min_point_beta = 0.5;      ///< points with a lower static score are left out
  double lambda_imu = 1.0;          ///< bias random-walk weight, Eq. 58
  bool visual_variance_estimation = true;  ///< LocalMapping.VisualVarianceEstimation
  /// Link the IMU across the losses between the two maps (bridgeOrigin, absorbBridgedMiddle;
  /// Loop.BridgeLosses)
  bool bridge_losses = true;
};

/// What the welding did (zero when it did not run).
struct WeldingResult {
  int fused_points = 0;   ///< duplicates across the seam merged (seam fusion)
  int linked_points = 0;  ///< observations added across the seam
  int optimised_keyframes = 0;
  int fixed_keyframes = 0;
  int points = 0;
  int inertial_links = 0;
  double initial_chi2 = 0.0;
  double final_chi2 = 0.0;
};

struct MergeResult {
  map::MapId source;    ///< the map of `current`, merged away
  map::MapId target;    ///< the map of the recognised place, kept
  SE3 T_target_source;  ///< applied to everything of `source` (4-DoF with gravity)
  int inliers = 0;      ///< RANSAC inliers of the place match
  /// Inertial links across a loss added by the merge (bridgeOrigin)
  int bridged = 0;
  /// Maps between the source and the target by consecutive losses merged with it
  /// (absorbBridgedMiddle)
  int absorbed = 0;
  LoopCorrectionResult correction;
  WeldingResult welding;
};

/// The IMU across the loss that started a map (map::MapOrigin::imu_across), once the parent's
/// keyframe and the map's first keyframe both lie in `map` (good, the first without a previous
/// keyframe, the parent's without a next one, in time order): the first keyframe's previous
/// keyframe and inertial link become the parent's keyframe and that preintegration (and the two
/// are joined by an essential-graph loop edge), so the visual-inertial BAs spread a rejoin's
/// correction over the dead-reckoned stretch and its keyframes.
/// Returns true when linked. Call with tracking and local mapping paused.
bool bridgeOrigin(map::Map& map, const map::MapOrigin& origin);

/// Most maps absorbBridgedMiddle merges between the target and the source.
inline constexpr std::size_t kMaxBridgedMiddleMaps = 4;

/// Maps left between consecutive losses (the target -> middle 1 -> ... -> middle n -> the source,
/// n <= kMaxBridgedMiddleMaps) that no place match reaches (they saw the static world only through
/// the occluder's gaps): once the source, which started from a keyframe of middle n, is merged into
/// the target, the middle maps hang between them on the IMU at both ends. They are merged too,
/// oldest first, each at the world its dead reckoning gave it (moved with its parent keyframe
/// since, 4-DoF with gravity), and every loss is bridged (bridgeOrigin), so the full BA places them.
/// Nothing is merged unless every loss of the chain kept its IMU and every parent keyframe is good.
/// `source_origin` is the merged source's origin; returns the number of maps merged. Call with
/// tracking and local mapping paused.
int absorbBridgedMiddle(map::Atlas& atlas, map::Map& target, const map::MapOrigin& source_origin,
                        const std::optional<Vec3>& g_w);

/// nullopt (and nothing changed) when both keyframes are in the same map or the place match fails
/// verification. Call with tracking and local mapping paused on both maps.
std::optional<MergeResult> mergeAtPlace(map::Atlas& atlas, const map::KeyFrame& current, const map::KeyFrame& candidate,
                                        const LoopOptions& options, const MergeOptions& merge = MergeOptions());

/// The merge itself, for a place already verified (`place`: current keyframe -> points of the
/// candidate's map, with the current keyframe's pose in that map's world): move the current map into
/// the candidate's frame (4-DoF with merge.g_w), correct across the seam and weld. mergeAtPlace
/// verifies by BoW matching and calls it; the loop closer's rejoin (Loop.Rejoin) finds the place by a
/// guided search. nullopt when both keyframes are in the same map.
std::optional<MergeResult> mergeWithPlace(map::Atlas& atlas, const map::KeyFrame& current,
                                          const map::KeyFrame& candidate, LoopClosure place,
                                          const MergeOptions& merge = MergeOptions());

/// The welding on its own (mergeAtPlace runs it with gravity): the points of the window around
/// `candidate` are fused into the keyframes of the window around `current` by projection (both
/// sides' duplicates of the same structure become one point), then the BA of both windows, the
/// keyframes just outside each window in time and up to welding_fixed_observers other observers
/// held; poses, velocities, biases and points written back. Visual-inertial with merge.g_w, vision
/// only without.
WeldingResult weldingBundleAdjust(map::Map& map, const map::KeyFrame& current, const map::KeyFrame& candidate,
                                  const MergeOptions& merge);

}  // namespace ltlo::loop
