#include "ltlo/loop/map_merger.h"

#include <memory>
#include <utility>
#include <vector>

#include "ltlo/core/log.h"
#include "ltlo/optim/bundle_adjust.h"
#include "ltlo/optim/pose_graph.h"
#include "map_ba.h"
#include "seam_fusion.h"

namespace ltlo::loop {

namespace {

bool usable(const std::shared_ptr<map::KeyFrame>& kf) { return kf != nullptr && !kf->isBad(); }

/// Walks the IMU chain from `start` (excluded) up to `count` keyframes backwards (or forwards),
/// adding them to `window`; the first keyframe beyond is returned as the border (may be null).
std::shared_ptr<map::KeyFrame> walkChain(const map::Map& map, const std::shared_ptr<map::KeyFrame>& start, int count,
                                         bool backwards, std::vector<std::shared_ptr<map::KeyFrame>>& window) {
  std::shared_ptr<map::KeyFrame> at = start;
  for (int n = 0; n <= count; ++n) {
    const std::shared_ptr<map::KeyFrame> next =
        map.keyFrame(backwards ? at->previousKeyFrame() : at->nextKeyFrame());
    if (!usable(next)) return nullptr;
    if (n == count) return next;
    window.push_back(next);
    at = next;
  }
  return nullptr;
}

}  // namespace

WeldingResult weldingBundleAdjust(map::Map& map, const map::KeyFrame& current, const map::KeyFrame& candidate,
                                  const MergeOptions& merge) {
  WeldingResult result;
  const std::shared_ptr<map::KeyFrame> current_kf = map.keyFrame(current.id());
  const std::shared_ptr<map::KeyFrame> candidate_kf = map.keyFrame(candidate.id());
  if (!usable(current_kf) || !usable(candidate_kf)) return result;
  // Current side: the keyframe and its predecessors; recognised side: the keyframe and its
  // neighbours in time, up to half after it and the rest before. The keyframes just beyond are
  // held, so the inertial links at the window's ends keep their velocities and biases.
  MapBaSelection selection;
  const int n = std::max(1, merge.welding_keyframes);
  selection.optimised.push_back(current_kf);
  if (auto border = walkChain(map, current_kf, n - 1, true, selection.optimised)) selection.fixed.push_back(border);
  const std::size_t candidate_start = selection.optimised.size();
  selection.optimised.push_back(candidate_kf);
  if (auto border = walkChain(map, candidate_kf, (n - 1) / 2, false, selection.optimised)) {
    selection.fixed.push_back(border);
  }
  const int after = static_cast<int>(selection.optimised.size() - candidate_start) - 1;
  if (auto border = walkChain(map, candidate_kf, n - 1 - after, true, selection.optimised)) {
    selection.fixed.push_back(border);
  }
  // Both sides still hold their own points of the structure around the place: fuse them, so the
  // BA welds the whole overlap, not only the points the place match fused.
  const std::vector<std::shared_ptr<map::KeyFrame>> current_side(
      selection.optimised.begin(), selection.optimised.begin() + static_cast<std::ptrdiff_t>(candidate_start));
  const std::vector<std::shared_ptr<map::KeyFrame>> candidate_side(
      selection.optimised.begin() + static_cast<std::ptrdiff_t>(candidate_start), selection.optimised.end());
  SeamFusionOptions fusion;
  fusion.bf_px_m = merge.bf_px_m;
  fusion.min_point_beta = merge.min_point_beta;
  const SeamFusionStats fused =
      fuseAcrossSeam(map, current_side, pointsSeenBy(map, candidate_side, merge.min_point_beta), fusion);
  result.fused_points = fused.replaced;
  result.linked_points = fused.linked;
  MapBaOptions build;
  build.bf_px_m = merge.bf_px_m;
  build.min_point_beta = merge.min_point_beta;
  build.g_w = merge.g_w;
  build.lambda_imu = merge.lambda_imu;
  build.visual_variance_estimation = merge.visual_variance_estimation;
  build.max_fixed_observers = merge.welding_fixed_observers;
  const MapBaProblem built = buildMapBa(map, selection, build);
  result.optimised_keyframes = built.optimised_keyframes;
  result.fixed_keyframes = built.fixed_keyframes;
  result.points = static_cast<int>(built.points.size());
  result.inertial_links = static_cast<int>(built.problem.inertial.size());
  if (built.optimised_keyframes == 0 || built.points.empty()) return result;

  optim::LocalBaOptions ba_options;
  ba_options.iterations = merge.welding_iterations;
  const optim::LocalBaResult solved = optim::localBundleAdjust(built.problem, ba_options);
  result.initial_chi2 = solved.initial_chi2;
  result.final_chi2 = solved.summary.final_chi2;
  const std::vector<bool> inertial = inertialKeyFrames(built);
  for (std::size_t k = 0; k < built.keyframes.size(); ++k) {
    map::KeyFrame& kf = *built.keyframes[k];
    const optim::BaKeyFrame& in = built.problem.keyframes[k];
    const optim::BaKeyFrame& out = solved.keyframes[k];
    if (kf.isBad() || !out.T_w_b.translation().allFinite()) continue;
    if (!in.fixed) kf.setPose_T_w_b(out.T_w_b);
    if (inertial[k] && (!in.fixed || in.fixed_pose_only) && out.v_w_b.allFinite()) {
      kf.setVelocity(out.v_w_b);
      kf.setBias(out.bias);
    }
  }
  for (std::size_t m = 0; m < built.points.size(); ++m) {
    if (!built.points[m]->isBad() && solved.points[m].p_w.allFinite()) built.points[m]->setPosition(solved.points[m].p_w);
  }
  map.bumpVersion();
  return result;
}

bool bridgeOrigin(map::Map& map, const map::MapOrigin& origin) {
  if (!origin.imu_across || !origin.parent_keyframe.valid() || !origin.first_keyframe.valid()) return false;
  const std::shared_ptr<map::KeyFrame> parent = map.keyFrame(origin.parent_keyframe);
  const std::shared_ptr<map::KeyFrame> first = map.keyFrame(origin.first_keyframe);
  if (!parent || !first || parent->isBad() || first->isBad()) return false;
  if (first->previousKeyFrame().valid() || parent->nextKeyFrame().valid() || !(parent->t_s() < first->t_s())) {
    return false;
  }
  first->setPreviousKeyFrame(parent->id());
  first->setImuFromPrevious(*origin.imu_across);
  parent->setNextKeyFrame(first->id());
  // Also an essential-graph edge: the two spanning trees are joined there, whatever place the
  // merge matched.
  parent->addLoopEdge(first->id());
  first->addLoopEdge(parent->id());
  map.bumpVersion();
  return true;
}

int absorbBridgedMiddle(map::Atlas& atlas, map::Map& target, const map::MapOrigin& source_origin,
                        const std::optional<Vec3>& g_w) {
  if (!source_origin.imu_across) return 0;
  // Walk back from the source's parent map to the target: every map on the way must have started
  // on the IMU across a loss from the map before it, whose keyframe it started from is good.
  struct Middle {
    map::MapId id;
    map::MapOrigin origin;
  };
  std::vector<Middle> chain;  // newest first
  map::MapId id = atlas.resolve(source_origin.parent);
  map::KeyFrameId needed = source_origin.parent_keyframe;  // in the map `id`
  while (true) {
    map::Map* on_chain = atlas.map(id);
    if (on_chain == nullptr) return 0;
    const std::shared_ptr<map::KeyFrame> from = on_chain->keyFrame(needed);
    if (!from || from->isBad()) return 0;
    if (id == target.id()) break;
    if (chain.size() == kMaxBridgedMiddleMaps) return 0;  // also ends any cycle of origins
    std::optional<map::MapOrigin> origin = on_chain->origin();
    if (!origin || !origin->imu_across) return 0;
    chain.push_back({id, std::move(*origin)});
    id = atlas.resolve(chain.back().origin.parent);
    needed = chain.back().origin.parent_keyframe;
  }
  if (chain.empty()) return 0;
  // Oldest first: each map's parent keyframe is in the target by the time it is merged.
  for (auto middle = chain.rbegin(); middle != chain.rend(); ++middle) {
    const std::shared_ptr<map::KeyFrame> anchor = target.keyFrame(middle->origin.parent_keyframe);
    SE3 T_target_middle = anchor->T_w_b() * middle->origin.T_w_b_parent_keyframe.inverse();
    if (g_w) T_target_middle = optim::fourDofCorrection(T_target_middle, *g_w, anchor->T_w_b().translation());
    const std::size_t keyframes = atlas.map(middle->id)->numKeyFrames();
    atlas.mergeMaps(middle->id, target.id(), T_target_middle);
    const bool linked = bridgeOrigin(target, middle->origin);
    log::info("merged ", middle->id, " (", keyframes, " keyframes) into ", target.id(),
              " between two losses, at its dead-reckoned place; the IMU across the loss before it linked: ",
              linked ? "yes" : "no");
  }
  const bool linked_source = bridgeOrigin(target, source_origin);
  log::info(chain.size(), " map(s) between losses merged into ", target.id(),
            "; the IMU across the last loss linked: ", linked_source ? "yes" : "no");
  return static_cast<int>(chain.size());
}

std::optional<MergeResult> mergeAtPlace(map::Atlas& atlas, const map::KeyFrame& current, const map::KeyFrame& candidate,
                                        const LoopOptions& options, const MergeOptions& merge) {
  const map::MapId source = current.mapId();
  const map::MapId target = candidate.mapId();
  if (source == target) return std::nullopt;
  map::Map* target_map = atlas.map(target);
  if (target_map == nullptr || atlas.map(source) == nullptr) return std::nullopt;

  std::optional<LoopClosure> place = verifyLoop(current, candidate, *target_map, options);
  if (!place) return std::nullopt;
  return mergeWithPlace(atlas, current, candidate, std::move(*place), merge);
}

std::optional<MergeResult> mergeWithPlace(map::Atlas& atlas, const map::KeyFrame& current,
                                          const map::KeyFrame& candidate, LoopClosure place,
                                          const MergeOptions& merge) {
  const map::MapId source = current.mapId();
  const map::MapId target = candidate.mapId();
  if (source == target) return std::nullopt;
  map::Map* target_map = atlas.map(target);
  if (target_map == nullptr || atlas.map(source) == nullptr) return std::nullopt;
  MergeResult result;
  result.source = source;
  result.target = target;
  result.inliers = static_cast<int>(place.matches.size());
  const SE3 T_w_b_current = current.T_w_b();
  result.T_target_source = place.T_w_b_current_corrected * T_w_b_current.inverse();
  if (merge.g_w) {
    // Both maps are in the run's gravity-aligned world: only yaw about gravity and translation
    // may differ (the current keyframe's position goes where the place match says).
    result.T_target_source = optim::fourDofCorrection(result.T_target_source, *merge.g_w, T_w_b_current.translation());
    place.T_w_b_current_corrected = result.T_target_source * T_w_b_current;
  }
  const std::optional<map::MapOrigin> source_origin = atlas.map(source)->origin();
  const std::optional<map::MapOrigin> target_origin = target_map->origin();
  atlas.mergeMaps(source, target, result.T_target_source);
  // Either map may have started from a keyframe of the other (or of a map merged into it before).
  if (merge.bridge_losses && source_origin && bridgeOrigin(*target_map, *source_origin)) ++result.bridged;
  if (merge.bridge_losses && target_origin && bridgeOrigin(*target_map, *target_origin)) ++result.bridged;
  if (merge.bridge_losses && source_origin && result.bridged == 0) {
    result.absorbed = absorbBridgedMiddle(atlas, *target_map, *source_origin, merge.g_w);
    if (result.absorbed > 0) result.bridged += result.absorbed + 1;
  }
  log::info("merged ", source, " into ", target, " at kf ", current.id(), " ~ kf ", candidate.id(), " (",
            result.inliers, " inliers, ", (merge.g_w ? "4-DoF" : "SE3"), " alignment",
            result.bridged > 0 ? ", the IMU across the loss linked" : "", ")");
  // The current keyframe is now in the target frame at (nearly) its corrected pose; the loop
  // correction fuses the duplicated points and ties the two spanning trees with the loop edge.
  LoopCorrectionOptions correction;
  correction.g_w = merge.g_w;
  result.correction = correctLoop(*target_map, place, correction);
  if (merge.g_w) {
    result.welding = weldingBundleAdjust(*target_map, current, candidate, merge);
    log::info("welding at the seam: ", result.welding.fused_points, " duplicate points fused, ",
              result.welding.linked_points, " observations added; BA ", result.welding.optimised_keyframes,
              " keyframes optimised, ",
              result.welding.fixed_keyframes, " held, ", result.welding.points, " points, ",
              result.welding.inertial_links, " inertial links, chi2 ", result.welding.initial_chi2, " -> ",
              result.welding.final_chi2);
  }
  return result;
}

}  // namespace ltlo::loop
