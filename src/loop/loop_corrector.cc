#include "ltlo/loop/loop_corrector.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "ltlo/map/essential_graph.h"
#include "ltlo/optim/pose_graph.h"

namespace ltlo::loop {

namespace {

features::OrbFeatures featuresOf(const map::KeyFrame& kf) {
  features::OrbFeatures f;
  f.keypoints = kf.keypoints();
  f.descriptors = kf.descriptors();
  return f;
}

std::pair<map::KeyFrameId, map::KeyFrameId> orderedPair(map::KeyFrameId a, map::KeyFrameId b) {
  return a < b ? std::make_pair(a, b) : std::make_pair(b, a);
}

}  // namespace

LoopCorrespondences findLoopCorrespondences(const map::KeyFrame& current, const map::KeyFrame& candidate,
                                            const map::Map& map, std::size_t num_covisibles,
                                            const features::GuidedMatchOptions& matching) {
  LoopCorrespondences out;
  std::vector<std::shared_ptr<map::KeyFrame>> loop_side;
  if (std::shared_ptr<map::KeyFrame> self = map.keyFrame(candidate.id())) loop_side.push_back(self);
  for (const map::KeyFrameId id : candidate.bestCovisibles(num_covisibles)) {
    if (id == current.id()) continue;
    if (std::shared_ptr<map::KeyFrame> kf = map.keyFrame(id)) loop_side.push_back(kf);
  }
  const features::OrbFeatures current_features = featuresOf(current);
  std::vector<bool> keypoint_used(static_cast<std::size_t>(current.numKeypoints()), false);
  std::unordered_set<map::MapPointId> point_used;
  for (const std::shared_ptr<map::KeyFrame>& kf : loop_side) {
    if (kf->isBad() || !kf->hasBow() || !current.hasBow()) continue;
    const features::OrbFeatures loop_features = featuresOf(*kf);
    const std::vector<features::Match> matches =
        features::matchByBow(current.featureVector(), current_features, kf->featureVector(), loop_features, matching);
    for (const features::Match& m : matches) {
      if (keypoint_used[static_cast<std::size_t>(m.query)] || current.depth_m(m.query) <= 0.0f) continue;
      const map::MapPointId point_id = kf->mapPoint(m.train);
      if (!point_id.valid() || point_used.count(point_id) > 0) continue;
      const std::shared_ptr<map::MapPoint> point = map.mapPoint(point_id);
      if (!point || point->isBad()) continue;
      keypoint_used[static_cast<std::size_t>(m.query)] = true;
      point_used.insert(point_id);
      place::Correspondence3d c;
      c.p_a = current.p_c(m.query);
      c.p_b = point->p_w();
      c.sigma_m = std::sqrt(2.0) * place::depthSigma_m(current.depth_m(m.query));  // both ends see similar depths
      out.correspondences.push_back(c);
      out.matches.push_back(LoopMatch{m.query, point_id});
    }
  }
  return out;
}

std::optional<LoopClosure> verifyLoop(const map::KeyFrame& current, const map::KeyFrame& candidate, const map::Map& map,
                                      const LoopOptions& options, place::Se3RansacResult* ransac_out) {
  LoopCorrespondences found = findLoopCorrespondences(current, candidate, map);
  place::Se3RansacOptions ransac_options;
  // The depth-noise gate grows with depth^2; Loop.InlierThreshold caps the inlier distance.
  const double max_sigma_m = options.inlier_threshold_m / std::sqrt(ransac_options.chi2_3d);
  for (place::Correspondence3d& c : found.correspondences) c.sigma_m = std::min(c.sigma_m, max_sigma_m);
  ransac_options.min_inliers = options.min_inliers;
  ransac_options.seed = static_cast<std::uint32_t>(current.id().value * 7919u + candidate.id().value);
  const place::Se3RansacResult ransac = place::estimateSe3Ransac(found.correspondences, ransac_options);
  if (ransac_out != nullptr) *ransac_out = ransac;
  log::debug("loop: kf ", current.id(), " vs ", candidate.id(), ": ", found.correspondences.size(), " 3-D matches, ",
             ransac.num_inliers, " inliers");
  if (!ransac.success) return std::nullopt;
  LoopClosure loop;
  loop.current = current.id();
  loop.loop = candidate.id();
  const SE3 T_c_w = ransac.T_a_b;
  loop.T_w_b_current_corrected = T_c_w.inverse() * current.T_b_c().inverse();
  for (std::size_t k = 0; k < found.matches.size(); ++k) {
    if (ransac.inliers[k]) loop.matches.push_back(found.matches[k]);
  }
  return loop;
}

namespace {

/// Keyframe poses by id, m and rad (T_w_b).
using KeyFramePoses = std::unordered_map<map::KeyFrameId, SE3>;

/// Pre-loop state: poses and the edges whose relative poses stay measurements.
struct PreLoopState {
  KeyFramePoses T_w_b_old;
  std::set<std::pair<map::KeyFrameId, map::KeyFrameId>> old_edges;
};

PreLoopState preLoopState(const map::Map& map, bool with_gravity) {
  PreLoopState state;
  const std::vector<std::shared_ptr<map::KeyFrame>> keyframes = map.keyFrames();
  for (const std::shared_ptr<map::KeyFrame>& kf : keyframes) state.T_w_b_old[kf->id()] = kf->T_w_b();
  for (const map::EssentialEdge& e : map::essentialGraphEdges(map, map::kEssentialCovisibilityWeight, with_gravity)) {
    state.old_edges.insert(orderedPair(e.from, e.to));
  }
  return state;
}

/// The current keyframe's covisible window (without the loop keyframe) after the loop's rigid
/// correction, and which window keyframe moved each of their points.
struct MovedWindow {
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;
  std::unordered_map<map::MapPointId, map::KeyFrameId> corrected_by;
};

/// 1. The current keyframe's covisible window moves rigidly with it: T_new = C * T_old (with
///    gravity: C's yaw and the translation that puts the current keyframe where the loop says).
MovedWindow moveWindowRigidly(map::Map& map, const LoopClosure& loop, const map::KeyFrame& loop_kf,
                              const std::shared_ptr<map::KeyFrame>& current, const SE3& T_w_b_current_old,
                              const LoopCorrectionOptions& options) {
  const bool with_gravity = options.g_w.has_value();
  SE3 C = loop.T_w_b_current_corrected * T_w_b_current_old.inverse();
  if (with_gravity) C = optim::fourDofCorrection(C, *options.g_w, T_w_b_current_old.translation());
  const Mat3 R_C = C.rotationMatrix();
  MovedWindow window;
  window.keyframes.push_back(current);
  for (const auto& [id, weight] : current->covisibles()) {
    if (id == loop_kf.id()) continue;
    // A loaded atlas's keyframe is the reference the window is corrected towards: it stays.
    if (std::shared_ptr<map::KeyFrame> kf = map.keyFrame(id); kf && !kf->isBad() && !kf->isAnchor()) {
      window.keyframes.push_back(kf);
    }
  }
  for (const std::shared_ptr<map::KeyFrame>& kf : window.keyframes) {
    for (const map::MapPointId point_id : kf->mapPoints()) {
      if (!point_id.valid() || window.corrected_by.count(point_id) > 0) continue;
      const std::shared_ptr<map::MapPoint> point = map.mapPoint(point_id);
      if (!point || point->isBad()) continue;
      point->setPosition(C * point->p_w());
      window.corrected_by[point_id] = kf->id();
    }
    kf->setPose_T_w_b(C * kf->T_w_b());
    if (with_gravity) kf->setVelocity(R_C * kf->v_w_b());
  }
  return window;
}

/// 2. Fusion: the current keyframe's keypoints take the loop points.
void fuseLoopPoints(map::Map& map, const LoopClosure& loop, map::KeyFrame& current, LoopCorrectionResult* result) {
  for (const LoopMatch& match : loop.matches) {
    const std::shared_ptr<map::MapPoint> loop_point = map.mapPoint(match.loop_point);
    if (!loop_point || loop_point->isBad()) continue;
    const map::MapPointId existing = current.mapPoint(match.keypoint);
    if (existing == match.loop_point) continue;
    if (existing.valid()) {
      if (map.replaceMapPoint(existing, match.loop_point)) ++result->fused_points;
    } else if (!loop_point->indexIn(current.id()) && map.addObservation(current, match.keypoint, *loop_point)) {
      ++result->added_observations;
    }
  }
}

/// The essential graph of the map's keyframes (from `keyframes`, the bad ones left out) with the
/// loop keyframe fixed.
struct EssentialPoseGraph {
  std::unordered_map<map::KeyFrameId, int> node_of;
  std::vector<optim::PoseGraphNode> nodes;
  KeyFramePoses T_w_b_input;  ///< the nodes' poses as given to the optimiser
  std::vector<optim::PoseGraphEdge> edges;
};

/// 3. Essential graph with the loop keyframe fixed. Edges that existed before the correction keep
///    their pre-loop relative pose; new ones take the corrected poses.
EssentialPoseGraph essentialPoseGraph(const map::Map& map, const std::vector<std::shared_ptr<map::KeyFrame>>& keyframes,
                                      map::KeyFrameId loop_kf, const PreLoopState& pre_loop, bool with_gravity) {
  EssentialPoseGraph graph;
  for (const std::shared_ptr<map::KeyFrame>& kf : keyframes) {
    if (kf->isBad()) continue;
    optim::PoseGraphNode node;
    node.id = static_cast<int>(graph.nodes.size());
    node.T_w_b = kf->T_w_b();
    node.fixed = kf->id() == loop_kf || kf->isAnchor();
    graph.node_of[kf->id()] = node.id;
    graph.T_w_b_input[kf->id()] = node.T_w_b;
    graph.nodes.push_back(node);
  }
  const KeyFramePoses& T_w_b_old = pre_loop.T_w_b_old;
  for (const map::EssentialEdge& e : map::essentialGraphEdges(map, map::kEssentialCovisibilityWeight, with_gravity)) {
    if (graph.node_of.count(e.from) == 0 || graph.node_of.count(e.to) == 0) continue;
    const bool existed = pre_loop.old_edges.count(orderedPair(e.from, e.to)) > 0 && T_w_b_old.count(e.from) > 0 &&
                         T_w_b_old.count(e.to) > 0;
    const KeyFramePoses& poses = existed ? T_w_b_old : graph.T_w_b_input;
    optim::PoseGraphEdge edge;
    edge.id_i = graph.node_of.at(e.from);
    edge.id_j = graph.node_of.at(e.to);
    edge.T_i_j = poses.at(e.from).inverse() * poses.at(e.to);
    graph.edges.push_back(edge);
  }
  return graph;
}

/// 4. Write back poses; returns each keyframe's correction T_new * T_input^-1.
KeyFramePoses writeOptimisedPoses(const std::vector<std::shared_ptr<map::KeyFrame>>& keyframes,
                                  const EssentialPoseGraph& graph, const optim::PoseGraphResult& optimised,
                                  bool with_gravity) {
  KeyFramePoses correction;  // T_new * T_input^-1
  for (const std::shared_ptr<map::KeyFrame>& kf : keyframes) {
    const auto it = graph.node_of.find(kf->id());
    if (it == graph.node_of.end()) continue;
    const SE3& T_new = optimised.nodes[static_cast<std::size_t>(it->second)].T_w_b;
    correction[kf->id()] = T_new * graph.T_w_b_input.at(kf->id()).inverse();
    kf->setPose_T_w_b(T_new);
    // The velocity is in the world frame: it turns with the pose (a yaw about gravity here).
    if (with_gravity) kf->setVelocity(correction[kf->id()].rotationMatrix() * kf->v_w_b());
  }
  return correction;
}

/// Points move with their keyframe's correction: the window keyframe that corrected them, else
/// their reference keyframe, else their first observer with a correction.
void movePointsWithKeyFrames(const map::Map& map, const std::unordered_map<map::MapPointId, map::KeyFrameId>& corrected_by,
                             const KeyFramePoses& correction) {
  for (const std::shared_ptr<map::MapPoint>& point : map.mapPoints()) {
    if (point->isBad()) continue;
    map::KeyFrameId by;
    if (const auto it = corrected_by.find(point->id()); it != corrected_by.end()) {
      by = it->second;
    } else {
      by = point->referenceKeyFrame();
    }
    if (!by.valid() || correction.count(by) == 0) {
      const map::Observations observations = point->observations();
      by = map::KeyFrameId();
      for (const auto& [id, index] : observations) {
        if (correction.count(id) > 0) {
          by = id;
          break;
        }
      }
    }
    if (!by.valid()) continue;
    point->setPosition(correction.at(by) * point->p_w());
  }
}

}  // namespace

LoopCorrectionResult correctLoop(map::Map& map, const LoopClosure& loop, const LoopCorrectionOptions& options) {
  LoopCorrectionResult result;
  const std::shared_ptr<map::KeyFrame> current = map.keyFrame(loop.current);
  const std::shared_ptr<map::KeyFrame> loop_kf = map.keyFrame(loop.loop);
  LTLO_ASSERT(current && loop_kf,
              "correctLoop: keyframe " << loop.current << " or " << loop.loop << " is not in map " << map.id());
  const bool with_gravity = options.g_w.has_value();
  const PreLoopState pre_loop = preLoopState(map, with_gravity);

  const MovedWindow window =
      moveWindowRigidly(map, loop, *loop_kf, current, pre_loop.T_w_b_old.at(current->id()), options);
  result.window_size = static_cast<int>(window.keyframes.size());

  fuseLoopPoints(map, loop, *current, &result);
  for (const std::shared_ptr<map::KeyFrame>& kf : window.keyframes) map.updateConnections(*kf);
  current->addLoopEdge(loop_kf->id());
  loop_kf->addLoopEdge(current->id());

  const std::vector<std::shared_ptr<map::KeyFrame>> nodes_kf = map.keyFrames();
  const EssentialPoseGraph graph = essentialPoseGraph(map, nodes_kf, loop_kf->id(), pre_loop, with_gravity);
  result.graph_edges = static_cast<int>(graph.edges.size());
  const optim::PoseGraphResult optimised =
      with_gravity ? optim::optimizePoseGraph4Dof(graph.nodes, graph.edges, *options.g_w, options.iterations)
                   : optim::optimizePoseGraph(graph.nodes, graph.edges, options.iterations);
  result.initial_cost = optimised.summary.initial_chi2;
  result.final_cost = optimised.summary.final_chi2;

  const KeyFramePoses correction = writeOptimisedPoses(nodes_kf, graph, optimised, with_gravity);
  movePointsWithKeyFrames(map, window.corrected_by, correction);
  map.bumpVersion();
  log::info("loop closed: kf ", loop.current, " -> kf ", loop.loop, ", window ", result.window_size, ", fused ",
            result.fused_points, ", ", (with_gravity ? "4-DoF" : "SE3"), " graph ", result.graph_edges,
            " edges, chi2 ", result.initial_cost, " -> ", result.final_cost);
  return result;
}

}  // namespace ltlo::loop
