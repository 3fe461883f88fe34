#include "ltlo/loop/loop_closer.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include "bow/bow_vector.h"
#include "ltlo/core/blocking_queue.h"
#include "ltlo/core/log.h"
#include "ltlo/loop/loop_corrector.h"
#include "ltlo/loop/loop_detector.h"
#include "ltlo/loop/map_merger.h"
#include "ltlo/map/keyframe_database.h"
#include "ltlo/place/pooled_place_match.h"
#include "loop_closer_impl.h"

namespace ltlo::loop {

// The place matching (place/) the rejoin and proximity searches are built on.
using place::GuidedPlaceMatch;
using place::GuidedPlaceMatchOptions;
using place::WorldOffsetVote;
using place::guidedPlaceMatch;
using place::pooledPlaceMatch;
using place::poolingWindow;
using place::translationWithHeldRotation;
using place::voteWorldOffset;
using place::withinPredictionGate;

namespace {

/// A merge candidate not (yet) consistent is accepted when its verification has this many times
/// Loop.MinInliers (a map started after tracking loss should rejoin the old one soon).
constexpr int kStrongMergeInlierFactor = 2;
/// Floor of the rejoin's position sigma: the new map's own drift from its origin (m).
constexpr double kRejoinDriftSigma_m = 0.02;
/// Sigmas of the rejoin's second search, around the first search's RANSAC pose (m, rad).
constexpr double kRejoinRefineSigma_m = 0.02;
constexpr double kRejoinRefineSigma_rad = 0.01;
/// Descriptor distance of a vote for the world offset (ORB's strict match threshold).
constexpr int kRejoinVoteDescriptorDistance = 50;
/// The proximity loop search (Loop.Proximity; its age and distance limits are Loop.ProximityMinAge
/// and Loop.ProximityMaxDistance): its rotation sigma; a found pose closer to kf's than both minima
/// is no loop to correct.
constexpr double kProximitySigma_rad = 0.01;
constexpr double kProximityMinCorrection_m = 0.01;
constexpr double kProximityMinCorrection_rad = 0.005;
/// Largest yaw sigma of a guided place match (rejoin, proximity loop) that may correct the map, rad
/// (GuidedPlaceMatch::yaw_sigma_rad). Measured on generated ltlo/mtlo/static runs: true rejoins and
/// proximity loops 0.07-0.32 deg; the two rejoins check_loops.py found false (3.2-3.3 deg off),
/// matched in a sliver of the view beside a box, 0.78 and 0.92 deg.
constexpr double kMaxCorrectionYawSigma_rad = 0.5 * M_PI / 180.0;
bool fixesYaw(const GuidedPlaceMatch& found) { return found.yaw_sigma_rad <= kMaxCorrectionYawSigma_rad; }
/// Ancestors of a map's origin chain searched by the rejoin (the parent first).
constexpr int kRejoinMaxAncestors = 4;

/// Path of the map's keyframes from t0_s to t1_s: the distances of consecutive keyframe positions
/// in time order, m (bad keyframes skipped).
double keyFramePathLength_m(const map::Map& map, double t0_s, double t1_s) {
  std::vector<std::pair<double, Vec3>> positions;
  for (const std::shared_ptr<map::KeyFrame>& kf : map.keyFrames()) {
    if (!kf->isBad() && kf->t_s() >= t0_s && kf->t_s() <= t1_s) {
      positions.emplace_back(kf->t_s(), kf->T_w_b().translation());
    }
  }
  std::sort(positions.begin(), positions.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  double length_m = 0.0;
  for (std::size_t k = 1; k < positions.size(); ++k) length_m += (positions[k].second - positions[k - 1].second).norm();
  return length_m;
}

/// Pauses local mapping, then holds tracking between two frames, for its lifetime (no-op functions
/// when not wired).
class MappingPause {
 public:
  explicit MappingPause(const MappingControl& mapping) : mapping_(mapping) {
    if (mapping_.pause) mapping_.pause();
    if (mapping_.hold_tracking) mapping_.hold_tracking();
  }
  MappingPause(const MappingPause&) = delete;
  MappingPause& operator=(const MappingPause&) = delete;
  ~MappingPause() {
    if (mapping_.release_tracking) mapping_.release_tracking();
    if (mapping_.resume) mapping_.resume();
  }

 private:
  const MappingControl& mapping_;
};

/// ORB-SLAM's BoW threshold: the lowest score of `kf` against its best covisibles (0 without any).
double minCovisibleScore(const map::KeyFrame& kf, const map::Map& map) {
  bool have_covisible = false;
  double min_score = 1.0;
  for (const map::KeyFrameId id : kf.bestCovisibles(kGroupSize)) {
    const std::shared_ptr<map::KeyFrame> other = map.keyFrame(id);
    if (!other || other->isBad() || !other->hasBow()) continue;
    min_score = std::min(min_score, bow::l1Score(kf.bowVector(), other->bowVector()));
    have_covisible = true;
  }
  return have_covisible ? min_score : 0.0;
}

/// The search in narrow windows around `T_w_c_centre` (a hypothesis, e.g. kf's pose moved by a
/// voted offset), gated against kf's own pose `T_w_c_gate` with `search`'s sigmas; not successful
/// outside the gate (the distances from T_w_c_gate are kept).
GuidedPlaceMatch searchNear(const map::KeyFrame& kf, const map::Map& map, const SE3& T_w_c_centre,
                            const SE3& T_w_c_gate, const GuidedPlaceMatchOptions& search) {
  GuidedPlaceMatchOptions narrow = search;
  narrow.sigma_position_m = kRejoinRefineSigma_m;
  narrow.sigma_rotation_rad = kRejoinRefineSigma_rad;
  narrow.apply_gate = false;  // the centre is a hypothesis: gated against kf's own pose below
  GuidedPlaceMatch found = guidedPlaceMatch(kf, map, T_w_c_centre, narrow);
  if (found.success && !withinPredictionGate(found.T_w_c, T_w_c_gate, search, &found.distance_m, &found.rotation_rad)) {
    found.success = false;
  }
  return found;
}

/// searchNear for a pooled window (window.front() is kf).
GuidedPlaceMatch pooledNear(const std::vector<std::shared_ptr<map::KeyFrame>>& window, const map::Map& map,
                            const SE3& T_w_c_centre, const SE3& T_w_c_gate, const GuidedPlaceMatchOptions& search,
                            bool hold_rotation = false) {
  GuidedPlaceMatchOptions narrow = search;
  narrow.sigma_position_m = kRejoinRefineSigma_m;
  narrow.sigma_rotation_rad = kRejoinRefineSigma_rad;
  narrow.apply_gate = false;
  GuidedPlaceMatch found = pooledPlaceMatch(window, map, T_w_c_centre, narrow, hold_rotation);
  if (found.success && !withinPredictionGate(found.T_w_c, T_w_c_gate, search, &found.distance_m, &found.rotation_rad)) {
    found.success = false;
  }
  return found;
}

/// The loop (or merge place) a successful guided search gives: kf's corrected pose and its inliers.
LoopClosure closureOf(const map::KeyFrame& kf, const GuidedPlaceMatch& found) {
  LoopClosure closure;
  closure.current = kf.id();
  closure.loop = found.nearest_keyframe->id();
  closure.T_w_b_current_corrected = found.T_w_c * kf.T_b_c().inverse();
  for (const auto& [keypoint, point] : found.matches) closure.matches.push_back(LoopMatch{keypoint, point});
  return closure;
}

}  // namespace

void LoopCloser::Impl::resetDetection() {
  detector = LoopDetector(options.loop, map::PlaceQueryOptions(), kGroupSize);
  merge_consistency.reset();
}

void LoopCloser::Impl::recordEvent(const LoopEvent& event) {
  std::lock_guard<std::mutex> lock(events_mutex);
  events.push_back(event);
  if (event.merge) {
    ++num_merges;
  } else {
    ++num_loops;
  }
}

void LoopCloser::Impl::scheduleRefinement(const map::Map& map) {
  refine_pending = options.run_global_ba && options.loop.refine_keyframes > 0;
  refine_map = map.id();
}

bool LoopCloser::Impl::fullBaFits(const map::Map& map) const {
  const double budget = options.loop.full_ba_budget;
  return budget <= 0.0 || static_cast<double>(full_ba_keyframes + map.numKeyFrames()) <=
                              budget * static_cast<double>(keyframes_received);
}

void LoopCloser::Impl::startBudgetedGlobalBa(map::Map& map, const std::optional<Vec3>& g_w) {
  full_ba_keyframes += map.numKeyFrames();
  startGlobalBa(map, g_w);
}

void LoopCloser::Impl::refineAfterCorrection(const std::shared_ptr<map::KeyFrame>& kf) {
  if (!refine_pending || keyframes_since_correction < options.loop.refine_keyframes || kf->isBad()) return;
  map::Map* map = atlas.map(kf->mapId());
  // A map merged away since: its successor holds the correction's keyframes.
  if (map == nullptr || atlas.resolve(refine_map) != map->id()) {
    refine_pending = false;
    return;
  }
  if (!fullBaFits(*map)) return;  // waits for the budget
  refine_pending = false;
  log::info("full BA of ", map->id(), " again at ", kf->id(), ", ", keyframes_since_correction,
            " keyframes after the last correction");
  startBudgetedGlobalBa(*map, gravity());
}

void LoopCloser::Impl::process(const std::shared_ptr<map::KeyFrame>& kf) {
  if (!kf || kf->isBad()) return;
  std::optional<ScopedTimer> timer;
  if (timing != nullptr) timer.emplace(*timing, "loop.keyframe");
  map::Map* map = atlas.map(kf->mapId());
  if (map == nullptr) return;
  if (map->id() != detection_map) {
    resetDetection();
    detection_map = map->id();
  }
  ++keyframes_since_correction;
  ++keyframes_received;
  if (options.loop.enabled) {
    bool closed = kf->hasBow() && tryLoop(kf, *map);
    if (!closed && options.loop.proximity) closed = tryProximityLoop(kf, *map);
    const bool rejoined = !closed && options.loop.rejoin && tryRejoin(kf, *map);
    if (!closed && !rejoined && kf->hasBow()) tryMerge(kf, *map);
  }
  refineAfterCorrection(kf);
  // After the queries, so the keyframe does not find itself.
  if (kf->hasBow() && !kf->isBad()) atlas.keyFrameDatabase().add(kf);
}

bool LoopCloser::Impl::tryLoop(const std::shared_ptr<map::KeyFrame>& kf, map::Map& map) {
  // Right after a correction the place just closed would be found again: no detection (as
  // ORB-SLAM), and the consistency starts afresh afterwards.
  if (keyframes_since_correction <= kKeyFramesBetweenLoops) return false;
  // Loop.WaitForImu: before the IMU is initialised no correction can be checked against the drift
  // (plausibleCorrection), and a map's first seconds may rest on a mover.
  if (options.loop.wait_for_imu && !gravity()) return false;
  const std::vector<std::shared_ptr<map::KeyFrame>> candidates =
      detector.detect(*kf, map, atlas.keyFrameDatabase());
  for (const std::shared_ptr<map::KeyFrame>& candidate : candidates) {
    if (candidate->isBad()) continue;
    const std::optional<LoopClosure> loop = verifyLoop(*kf, *candidate, map, options.loop);
    if (!loop) continue;
    if (!plausibleCorrection(*kf, *candidate, *loop, map)) continue;
    return correct(kf, candidate, *loop, map, false);
  }
  return false;
}

bool LoopCloser::Impl::plausibleCorrection(const map::KeyFrame& kf, const map::KeyFrame& candidate,
                                           const LoopClosure& loop, const map::Map& map) const {
  if (options.loop.max_correction_share <= 0.0 || !gravity()) return true;
  const double correction_m = (loop.T_w_b_current_corrected.translation() - kf.T_w_b().translation()).norm();
  const double path_m =
      keyFramePathLength_m(map, std::min(candidate.t_s(), kf.t_s()), std::max(candidate.t_s(), kf.t_s()));
  const double limit_m = 3.0 * options.loop.proximity_sigma_m + options.loop.max_correction_share * path_m;
  if (correction_m <= limit_m) return true;
  log::info("loop rejected: ", kf.id(), " ~ ", candidate.id(), " in ", map.id(), " (", loop.matches.size(),
            " inliers) would move the keyframe by ", correction_m, " m, more than the ", limit_m,
            " m drift allows over the ", path_m, " m since (Loop.MaxCorrectionShare)");
  return false;
}

GuidedPlaceMatchOptions LoopCloser::Impl::guidedSearch(const map::KeyFrame& kf, double sigma_position_m,
                                                       double sigma_rotation_rad, std::uint32_t salt) const {
  GuidedPlaceMatchOptions search = options.rejoin_search;
  search.sigma_position_m = sigma_position_m;
  search.sigma_rotation_rad = sigma_rotation_rad;
  search.seed = static_cast<std::uint32_t>(kf.id().value) * 7919u + salt;
  search.refine_pose = true;
  search.bf_px_m = kf.camera().fx() * options.virtual_baseline_m;
  return search;
}

bool LoopCloser::Impl::tryProximityLoop(const std::shared_ptr<map::KeyFrame>& kf, map::Map& map) {
  if (keyframes_since_correction <= kKeyFramesBetweenLoops || !gravity()) return false;
  GuidedPlaceMatchOptions search = guidedSearch(*kf, options.loop.proximity_sigma_m, kProximitySigma_rad, 37u);
  // Old keyframes only, outside kf's neighbourhood, in reach of kf's view.
  search.max_keyframe_t_s = kf->t_s() - options.loop.proximity_min_age_s;
  search.max_keyframe_distance_m = options.loop.proximity_max_distance_m;
  search.excluded_keyframes.push_back(kf->id());
  for (const auto& [id, weight] : kf->covisibles()) search.excluded_keyframes.push_back(id);
  const SE3 T_w_c = kf->T_w_c();
  const WorldOffsetVote vote = voteWorldOffset(*kf, map, T_w_c, search, kRejoinVoteDescriptorDistance);
  if (!vote.found) {
    if (vote.pairs > 0) {
      log::debug("proximity loop: ", kf->id(), " in ", map.id(), ": ", vote.pairs, " pairs, ", vote.support,
                 " at the peak: no offset");
    }
    return false;
  }
  const GuidedPlaceMatch found =
      searchNear(*kf, map, SE3(T_w_c.quaternion(), T_w_c.translation() + vote.offset_w), T_w_c, search);
  log::debug("proximity loop: ", kf->id(), " in ", map.id(), ": ", vote.pairs, " pairs, ", vote.support,
             " at the peak, ", found.matches.size(), " inliers, ", found.distance_m, " m / ",
             found.rotation_rad * 180.0 / M_PI, " deg from its pose, yaw sigma ", found.yaw_sigma_rad * 180.0 / M_PI,
             " deg", found.success ? "" : ": rejected");
  if (!found.success || static_cast<int>(found.matches.size()) < options.loop.min_inliers || !found.nearest_keyframe ||
      !fixesYaw(found)) {
    return false;
  }
  // Tracking may already have matched the old points: nothing left to correct.
  if (found.distance_m < kProximityMinCorrection_m && found.rotation_rad < kProximityMinCorrection_rad) return false;
  return correct(kf, found.nearest_keyframe, closureOf(*kf, found), map, true);
}

bool LoopCloser::Impl::correct(const std::shared_ptr<map::KeyFrame>& kf, const std::shared_ptr<map::KeyFrame>& candidate,
                               const LoopClosure& loop, map::Map& map, bool proximity) {
  std::optional<ScopedTimer> timer;
  if (timing != nullptr) timer.emplace(*timing, "loop.correction");
  LoopEvent event;
  event.proximity = proximity;
  event.t_s = kf->t_s();
  event.current = kf->id();
  event.loop = candidate->id();
  event.map = map.id();
  event.inliers = static_cast<int>(loop.matches.size());
  event.correction_m = (loop.T_w_b_current_corrected.translation() - kf->T_w_b().translation()).norm();
  // The full BA works on a snapshot it writes back: abort it before the map changes under it.
  abortGlobalBa();
  LoopCorrectionResult correction;
  LoopCorrectionOptions correction_options;
  {
    MappingPause pause(mapping);
    // Local mapping may have culled either end since the verification.
    if (kf->isBad() || candidate->isBad()) return false;
    // Read with local mapping held, so no IMU refinement changes gravity meanwhile.
    correction_options.g_w = gravity();
    correction = correctLoop(map, loop, correction_options);  // bumps the map's version (tracking refreshes)
  }
  if (timer) timer->stop();
  log::info(proximity ? "loop closed (proximity): " : "loop closed: ", kf->id(), " ~ ", candidate->id(), " in ",
            map.id(), " (", event.inliers, " inliers, correction ", event.correction_m, " m; window ",
            correction.window_size, ", fused ", correction.fused_points, ", added ", correction.added_observations, ")");
  recordEvent(event);
  keyframes_since_correction = 0;
  resetDetection();
  if (!options.run_global_ba) return true;
  if (fullBaFits(map)) {
    startBudgetedGlobalBa(map, correction_options.g_w);
    scheduleRefinement(map);
  } else {
    // The correction alone for now; the full BA follows as the refining one would, once it fits.
    log::info("full BA of ", map.id(), " after this loop waits for Loop.FullBaBudget (", full_ba_keyframes,
              " keyframes of full BAs for ", keyframes_received, " keyframes)");
    refine_pending = true;
    refine_map = map.id();
  }
  return true;
}

bool LoopCloser::Impl::tryMerge(const std::shared_ptr<map::KeyFrame>& kf, map::Map& map) {
  if (kf->staticAreaRatio() < options.loop.min_static_ratio) return false;
  map::PlaceQueryOptions query;
  query.group_size = kGroupSize;
  query.min_score = minCovisibleScore(*kf, map);
  const std::vector<map::PlaceCandidate> candidates =
      atlas.keyFrameDatabase().detectMergeCandidates(*kf, options.loop.min_static_ratio, query);
  if (candidates.empty()) {
    merge_consistency.reset();
    return false;
  }
  std::vector<CandidateGroup> groups;
  for (const map::PlaceCandidate& candidate : candidates) {
    groups.push_back(CandidateGroup{candidate.keyframe->id(), candidate.keyframe->bestCovisibles(kGroupSize)});
  }
  const std::vector<map::KeyFrameId> consistent = merge_consistency.update(groups);

  // Consistent candidates with the ordinary verification, else the best one with a strong one.
  std::shared_ptr<map::KeyFrame> accepted;
  for (const map::PlaceCandidate& candidate : candidates) {
    if (std::find(consistent.begin(), consistent.end(), candidate.keyframe->id()) == consistent.end()) continue;
    map::Map* target = atlas.map(candidate.keyframe->mapId());
    if (target == nullptr || candidate.keyframe->isBad()) continue;
    if (verifyLoop(*kf, *candidate.keyframe, *target, options.loop)) {
      accepted = candidate.keyframe;
      break;
    }
  }
  if (!accepted) {
    const std::shared_ptr<map::KeyFrame>& best = candidates.front().keyframe;
    map::Map* target = atlas.map(best->mapId());
    LoopOptions strong = options.loop;
    strong.min_inliers = kStrongMergeInlierFactor * options.loop.min_inliers;
    if (target != nullptr && !best->isBad() && verifyLoop(*kf, *best, *target, strong)) accepted = best;
  }
  if (!accepted) return false;
  return merge(kf, accepted, std::nullopt);
}

bool LoopCloser::Impl::tryRejoin(const std::shared_ptr<map::KeyFrame>& kf, map::Map& map) {
  const std::optional<map::MapOrigin> origin = map.origin();
  if (!origin || !gravity()) return false;  // the shared world needs the IMU's gravity
  // The chain of origins: a map started from a map that itself started at a prediction shares the
  // world of every ancestor, within the accumulated sigma. A map merged away stands for the map
  // it went into, moved by its own origin's error.
  double sigma_m = std::hypot(origin->sigma_position_m, kRejoinDriftSigma_m);
  double sigma_rad = origin->sigma_rotation_rad;
  map::MapId ancestor = origin->parent;
  std::vector<map::MapId> searched{map.id()};
  for (int depth = 0; depth < kRejoinMaxAncestors; ++depth) {
    map::Map* ancestor_map = atlas.map(ancestor);
    if (ancestor_map == nullptr) break;
    const std::optional<map::MapOrigin> ancestor_origin = ancestor_map->origin();
    const map::MapId target_id = atlas.resolve(ancestor);
    double target_sigma_m = sigma_m, target_sigma_rad = sigma_rad;
    if (target_id != ancestor && ancestor_origin) {
      target_sigma_m = std::hypot(sigma_m, ancestor_origin->sigma_position_m);
      target_sigma_rad = std::hypot(sigma_rad, ancestor_origin->sigma_rotation_rad);
    }
    // Beyond this the prediction no longer knows where the map is: not a guided search (BoW may
    // still merge it).
    if (target_sigma_m > options.loop.rejoin_max_sigma_m) break;  // Loop.RejoinMaxSigma
    if (std::find(searched.begin(), searched.end(), target_id) == searched.end()) {
      searched.push_back(target_id);
      map::Map* target = atlas.map(target_id);
      if (target != nullptr && target->numKeyFrames() > 0 &&
          rejoinAt(kf, map, *target, target_sigma_m, target_sigma_rad)) {
        return true;
      }
    }
    if (!ancestor_origin) break;
    sigma_m = std::hypot(sigma_m, ancestor_origin->sigma_position_m);
    sigma_rad = std::hypot(sigma_rad, ancestor_origin->sigma_rotation_rad);
    ancestor = ancestor_origin->parent;
  }
  return false;
}

bool LoopCloser::Impl::rejoinAt(const std::shared_ptr<map::KeyFrame>& kf, map::Map& map, map::Map& target,
                                double sigma_position_m, double sigma_rotation_rad) {
  const GuidedPlaceMatchOptions search = guidedSearch(*kf, sigma_position_m, sigma_rotation_rad, 31u);
  const SE3 T_w_c = kf->T_w_c();
  // First the offset of kf's world by voting (robust to the look-alikes a window of the origin's
  // sigma holds), then the search around the offset pose; else the search in the wide windows.
  const WorldOffsetVote vote = voteWorldOffset(*kf, target, T_w_c, search, kRejoinVoteDescriptorDistance);
  GuidedPlaceMatch found;
  if (vote.found) {
    found = searchNear(*kf, target, SE3(T_w_c.quaternion(), T_w_c.translation() + vote.offset_w), T_w_c, search);
  }
  log::debug("rejoin vote: ", kf->id(), " of ", map.id(), " against ", target.id(), ": ", vote.pairs, " pairs, ",
             vote.support, " at the peak, offset ", vote.offset_w.transpose(), " m",
             found.success ? ", found" : "");
  if (!found.success) found = guidedPlaceMatch(*kf, target, T_w_c, search);
  if (found.success) {
    // The windows of the origin's sigma are wide (up to the cap) and the loose ratio test passes
    // few right matches: search again around the found pose in the windows of its own accuracy,
    // still gated against kf's pose.
    GuidedPlaceMatch refined = searchNear(*kf, target, found.T_w_c, T_w_c, search);
    if (refined.success && refined.matches.size() > found.matches.size()) found = std::move(refined);
  }
  int inliers = static_cast<int>(found.matches.size());
  log::debug("rejoin: ", kf->id(), " of ", map.id(), " against ", target.id(), " (sigma ", sigma_position_m,
             " m): ", found.keyframes, " keyframes, ", found.projected, " points projected, ", found.correspondences,
             " matches, ", found.ransac_inliers, " RANSAC inliers, ", found.refined_inliers, " refined, ",
             found.distance_m, " m / ", found.rotation_rad * 180.0 / M_PI, " deg from its pose",
             found.success ? "" : ": rejected");
  // The keyframe alone may see too little of the static world (a strip beside an occluder): pooled
  // with its best covisibles of its own map, around the pose found or else the voted offset.
  std::vector<std::shared_ptr<map::KeyFrame>> window;  // non-empty when the pooled result is taken
  if (options.loop.rejoin_pool > 1 && (found.success || vote.found)) window = poolingWindow(kf, map, options.loop.rejoin_pool);
  if (window.size() <= 1) window.clear();
  if (!window.empty()) {
    const SE3 centre = found.success ? found.T_w_c : SE3(T_w_c.quaternion(), T_w_c.translation() + vote.offset_w);
    GuidedPlaceMatch pooled = pooledNear(window, target, centre, T_w_c, search);
    if (pooled.success) {
      // Again around the pooled pose: the windows then sit where the points are.
      GuidedPlaceMatch again = pooledNear(window, target, pooled.T_w_c, T_w_c, search);
      if (again.success && again.refined_inliers >= pooled.refined_inliers) pooled = std::move(again);
    }
    log::debug("rejoin pooled: ", kf->id(), " with ", pooled.views - 1, " covisibles of ", map.id(), " against ",
               target.id(), ": ", pooled.correspondences, " matches, ", pooled.ransac_inliers, " RANSAC inliers, ",
               pooled.refined_inliers, " refined (", pooled.matches.size(), " of its own), ", pooled.distance_m,
               " m / ", pooled.rotation_rad * 180.0 / M_PI, " deg from its pose, yaw sigma ",
               pooled.yaw_sigma_rad * 180.0 / M_PI, " deg", pooled.success ? "" : ": rejected");
    if (pooled.success && pooled.refined_inliers > inliers) {
      found = std::move(pooled);
      inliers = found.refined_inliers;
    } else {
      window.clear();  // the keyframe's own result stands
    }
  }
  if (!found.success || inliers < options.loop.min_inliers || !found.nearest_keyframe) return false;
  if (!fixesYaw(found)) {
    // The matches cannot fix the yaw, but the dead reckoning that placed the map may know it well
    // enough (gyro drift over the stretch): then they fix the translation under the held rotation.
    GuidedPlaceMatch held;
    if (sigma_rotation_rad <= kMaxCorrectionYawSigma_rad) {
      if (window.empty()) {
        held = translationWithHeldRotation(*kf, target, found, T_w_c, options.loop.min_inliers);
      } else {
        held = pooledNear(window, target, SE3(T_w_c.quaternion(), found.T_w_c.translation()), T_w_c, search, true);
        held.success = held.success && held.refined_inliers >= options.loop.min_inliers;
        held.distance_m = (held.T_w_c.translation() - T_w_c.translation()).norm();
      }
    }
    if (!held.success || held.distance_m > search.gate_sigmas * sigma_position_m) {
      log::info("rejoin: ", kf->id(), " of ", map.id(), " found ", target.id(), " with ", inliers,
                " inliers, but their yaw sigma ", found.yaw_sigma_rad * 180.0 / M_PI, " deg is too wide to correct by");
      return false;
    }
    LoopClosure place = closureOf(*kf, held);
    log::info("rejoin: ", kf->id(), " of ", map.id(), " found ", target.id(), " at ", held.distance_m,
              " m from its pose (sigma ", sigma_position_m, " m), ",
              window.empty() ? static_cast<int>(held.matches.size()) : held.refined_inliers, " inliers",
              window.empty() ? "" : " (pooled)", " near ", place.loop,
              "; their yaw sigma ", found.yaw_sigma_rad * 180.0 / M_PI, " deg is too wide, the prediction's rotation (sigma ",
              sigma_rotation_rad * 180.0 / M_PI, " deg) held");
    return merge(kf, held.nearest_keyframe, std::move(place));
  }
  LoopClosure place = closureOf(*kf, found);
  log::info("rejoin: ", kf->id(), " of ", map.id(), " found ", target.id(), " at ", found.distance_m,
            " m from its pose (sigma ", sigma_position_m, " m), ", inliers, " inliers", window.empty() ? "" : " (pooled)",
            " near ", place.loop, ", yaw sigma ",
            found.yaw_sigma_rad * 180.0 / M_PI, " deg");
  return merge(kf, found.nearest_keyframe, std::move(place));
}

bool LoopCloser::Impl::merge(const std::shared_ptr<map::KeyFrame>& kf, const std::shared_ptr<map::KeyFrame>& accepted,
                             std::optional<LoopClosure> place) {
  const bool rejoin = place.has_value();
  std::optional<ScopedTimer> timer;
  if (timing != nullptr) timer.emplace(*timing, "loop.correction");
  const SE3 T_w_b_before = kf->T_w_b();
  abortGlobalBa();
  std::optional<MergeResult> merged;
  MergeOptions merge_options;
  merge_options.bf_px_m = kf->camera().K()(0, 0) * options.virtual_baseline_m;
  merge_options.min_point_beta = options.min_point_beta;
  merge_options.lambda_imu = options.lambda_imu;
  merge_options.visual_variance_estimation = options.visual_variance_estimation;
  merge_options.bridge_losses = options.loop.bridge_losses;
  {
    MappingPause pause(mapping);
    if (kf->isBad() || accepted->isBad()) return false;
    merge_options.g_w = gravity();
    // Atlas::mergeMaps bumps both versions and makes the target active if the source was;
    // correctLoop and the welding BA bump the target's again.
    merged = rejoin ? mergeWithPlace(atlas, *kf, *accepted, std::move(*place), merge_options)
                    : mergeAtPlace(atlas, *kf, *accepted, options.loop, merge_options);
  }
  if (timer) timer->stop();
  if (!merged) return false;
  LoopEvent event;
  event.merge = true;
  event.rejoin = rejoin;
  event.t_s = kf->t_s();
  event.current = kf->id();
  event.loop = accepted->id();
  event.map = merged->target;
  event.inliers = merged->inliers;
  event.correction_m = (kf->T_w_b().translation() - T_w_b_before.translation()).norm();
  log::info(rejoin ? "maps rejoined: " : "maps merged: ", merged->source, " into ", merged->target, " at ", kf->id(),
            " ~ ", accepted->id(), " (", event.inliers, " inliers)");
  recordEvent(event);
  keyframes_since_correction = 0;
  resetDetection();
  detection_map = merged->target;
  map::Map* target = atlas.map(merged->target);
  if (options.run_global_ba && target != nullptr) {
    startBudgetedGlobalBa(*target, merge_options.g_w);
    scheduleRefinement(*target);
  }
  return true;
}

void LoopCloser::Impl::startGlobalBa(map::Map& map, const std::optional<Vec3>& g_w) {
  abortGlobalBa();
  ba_stop.store(false);
  {
    std::lock_guard<std::mutex> lock(ba_mutex);
    ba_running = true;
  }
  if (in_run.load()) {
    ba_thread = std::thread([this, &map, g_w] { globalBa(map, g_w); });
  } else {
    globalBa(map, g_w);
  }
}

void LoopCloser::Impl::globalBa(map::Map& map, const std::optional<Vec3>& g_w) {
  if (in_run.load()) log::setThreadName("loop.ba");
  try {
    std::optional<ScopedTimer> timer;
    if (timing != nullptr) timer.emplace(*timing, "loop.global_ba");
    GlobalBaOptions ba_options;
    ba_options.iterations = options.loop.full_ba_iterations;
    ba_options.virtual_baseline_m = options.virtual_baseline_m;
    ba_options.min_point_beta = options.min_point_beta;
    ba_options.g_w = g_w;
    ba_options.lambda_imu = options.lambda_imu;
    ba_options.visual_variance_estimation = options.visual_variance_estimation;
    ba_options.stop_flag = &ba_stop;
    ba_options.estimate_gravity = options.loop.full_ba_gravity && mapping.set_gravity_w != nullptr;
    const GlobalBaSolution solution = optimizeGlobalBundleAdjustment(map, ba_options);
    if (solution.valid && !ba_stop.load()) {
      // Local BA writes the same poses and points: it holds while the result is written.
      MappingPause pause(mapping);
      if (!ba_stop.load()) {
        applyGlobalBundleAdjustment(map, solution);
        if (solution.g_w_after) mapping.set_gravity_w(*solution.g_w_after);
      }
    } else if (ba_stop.load()) {
      log::info("global BA of ", map.id(), " aborted");
    }
  } catch (const std::exception& e) {
    log::error("global BA of ", map.id(), " failed: ", e.what());
  }
  {
    std::lock_guard<std::mutex> lock(ba_mutex);
    ba_running = false;
  }
  ba_done.notify_all();
}

void LoopCloser::Impl::abortGlobalBa() {
  if (!ba_thread.joinable()) return;
  ba_stop.store(true);
  ba_thread.join();
}

void LoopCloser::Impl::joinGlobalBa() {
  if (ba_thread.joinable()) ba_thread.join();
}

LoopCloser::LoopCloser(map::Atlas& atlas, const LoopCloserOptions& options, MappingControl mapping,
                       TimingStats* timing)
    : impl_(std::make_unique<Impl>(atlas, options, std::move(mapping), timing)) {}

LoopCloser::~LoopCloser() { impl_->abortGlobalBa(); }

void LoopCloser::insertKeyFrame(std::shared_ptr<map::KeyFrame> kf) {
  if (!kf) return;
  // Never blocks the caller (local mapping): the loop thread may be waiting for local mapping to
  // pause, so a blocking push on a full queue could deadlock. A keyframe loop closing cannot take
  // (queue full, or finished) still enters the database for relocalisation and later queries.
  std::shared_ptr<map::KeyFrame> copy = kf;
  if (impl_->queue.tryPush(std::move(copy))) return;
  if (!impl_->queue.closed()) log::warn("loop closing queue full: ", kf->id(), " not queried for loops");
  if (kf->hasBow() && !kf->isBad()) impl_->atlas.keyFrameDatabase().add(kf);
}

void LoopCloser::processKeyFrame(const std::shared_ptr<map::KeyFrame>& kf) { impl_->process(kf); }

void LoopCloser::run() {
  log::setThreadName("loop");
  impl_->in_run.store(true);
  map::KeyFrameId current;
  try {
    while (std::optional<std::shared_ptr<map::KeyFrame>> kf = impl_->queue.pop()) {
      current = *kf ? (*kf)->id() : map::KeyFrameId();
      impl_->process(*kf);
    }
  } catch (const std::exception& e) {
    log::error("loop closing stopped at ", current, ": ", e.what());
    impl_->queue.close();
  }
  impl_->joinGlobalBa();
  impl_->in_run.store(false);
}

void LoopCloser::requestFinish() { impl_->queue.close(); }

std::size_t LoopCloser::queuedKeyFrames() const { return impl_->queue.size(); }

std::vector<LoopEvent> LoopCloser::events() const {
  std::lock_guard<std::mutex> lock(impl_->events_mutex);
  return impl_->events;
}

int LoopCloser::numLoops() const {
  std::lock_guard<std::mutex> lock(impl_->events_mutex);
  return impl_->num_loops;
}

int LoopCloser::numMerges() const {
  std::lock_guard<std::mutex> lock(impl_->events_mutex);
  return impl_->num_merges;
}

bool LoopCloser::globalBaRunning() const {
  std::lock_guard<std::mutex> lock(impl_->ba_mutex);
  return impl_->ba_running;
}

void LoopCloser::waitForGlobalBa() {
  std::unique_lock<std::mutex> lock(impl_->ba_mutex);
  impl_->ba_done.wait(lock, [&] { return !impl_->ba_running; });
}

int LoopCloser::finalGlobalBa() {
  Impl& impl = *impl_;
  if (!impl.options.run_global_ba || !impl.options.loop.final_full_ba) return 0;
  impl.joinGlobalBa();
  waitForGlobalBa();
  int adjusted = 0;
  for (const map::MapId id : impl.atlas.mapIds()) {
    map::Map* map = impl.atlas.map(id);
    if (map == nullptr || map->numKeyFrames() < 3) continue;
    // A loaded map held as the world's reference (Loop.HoldLoadedMap) and not extended: nothing to adjust.
    const std::vector<std::shared_ptr<map::KeyFrame>> keyframes = map->keyFrames();
    if (std::all_of(keyframes.begin(), keyframes.end(),
                    [](const std::shared_ptr<map::KeyFrame>& kf) { return kf->isAnchor(); })) {
      continue;
    }
    log::info("final full BA of ", id, " (Loop.FinalFullBa): ", keyframes.size(), " keyframes");
    impl.ba_stop.store(false);
    {
      std::lock_guard<std::mutex> lock(impl.ba_mutex);
      impl.ba_running = true;
    }
    impl.globalBa(*map, impl.gravity());
    ++adjusted;
  }
  return adjusted;
}

}  // namespace ltlo::loop
