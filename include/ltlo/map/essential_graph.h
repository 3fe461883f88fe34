#pragma once
/// The essential graph of a map as a plain edge list for pose-graph optimisation: spanning tree,
/// strong covisibility edges and loop edges, and (with the IMU) the links between keyframes
/// consecutive in time.
#include <vector>

#include "ltlo/map/ids.h"
#include "ltlo/map/map.h"

namespace ltlo::map {

/// Strong covisibility: edges with at least this many shared points join the essential graph.
inline constexpr int kEssentialCovisibilityWeight = 100;

enum class EdgeKind { kSpanningTree, kCovisibility, kLoop, kInertial };

struct EssentialEdge {
  KeyFrameId from;  ///< spanning tree: the child; inertial: the earlier; otherwise the lower id
  KeyFrameId to;    ///< spanning tree: the parent; inertial: the later; otherwise the higher id
  EdgeKind kind = EdgeKind::kSpanningTree;
  int weight = 0;  ///< shared map points between the two keyframes (0 if not covisible)
};

/// Each keyframe pair appears once, preferring spanning tree, then loop, then inertial, then
/// covisibility; bad keyframes and edges to keyframes not in `map` are left out. Sorted by (kind,
/// from, to). `with_inertial`: also each keyframe and its previousKeyFrame() (the IMU chain, which
/// keeps the trajectory stiff where covisibility is weak, e.g. through an occlusion).
/// Thread-safe (works on a snapshot of the map).
std::vector<EssentialEdge> essentialGraphEdges(const Map& map,
                                               int min_covisibility_weight = kEssentialCovisibilityWeight,
                                               bool with_inertial = false);

}  // namespace ltlo::map
