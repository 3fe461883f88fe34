#include "ltlo/map/essential_graph.h"

#include <algorithm>
#include <set>
#include <tuple>
#include <unordered_set>
#include <utility>

namespace ltlo::map {

std::vector<EssentialEdge> essentialGraphEdges(const Map& map, int min_covisibility_weight, bool with_inertial) {
  const std::vector<std::shared_ptr<KeyFrame>> keyframes = map.keyFrames();
  std::unordered_set<KeyFrameId> present;
  for (const std::shared_ptr<KeyFrame>& kf : keyframes) {
    if (!kf->isBad()) present.insert(kf->id());
  }
  std::set<std::pair<KeyFrameId, KeyFrameId>> linked;  // unordered pairs, stored (low, high)
  // Ids are returned by value: order them into values, never keep std::minmax's references.
  auto ordered = [](KeyFrameId a, KeyFrameId b) { return a < b ? std::make_pair(a, b) : std::make_pair(b, a); };
  auto claim = [&](KeyFrameId a, KeyFrameId b) {
    return present.count(a) > 0 && present.count(b) > 0 && linked.insert(ordered(a, b)).second;
  };
  std::vector<EssentialEdge> edges;
  for (const std::shared_ptr<KeyFrame>& kf : keyframes) {
    const KeyFrameId parent = kf->parent();
    if (parent.valid() && claim(kf->id(), parent)) {
      edges.push_back({kf->id(), parent, EdgeKind::kSpanningTree, kf->weight(parent)});
    }
  }
  for (const std::shared_ptr<KeyFrame>& kf : keyframes) {
    for (KeyFrameId other : kf->loopEdges()) {
      if (claim(kf->id(), other)) {
        const auto [low, high] = ordered(kf->id(), other);
        edges.push_back({low, high, EdgeKind::kLoop, kf->weight(other)});
      }
    }
  }
  if (with_inertial) {
    for (const std::shared_ptr<KeyFrame>& kf : keyframes) {
      const KeyFrameId previous = kf->previousKeyFrame();
      if (previous.valid() && claim(previous, kf->id())) {
        edges.push_back({previous, kf->id(), EdgeKind::kInertial, kf->weight(previous)});
      }
    }
  }
  for (const std::shared_ptr<KeyFrame>& kf : keyframes) {
    for (KeyFrameId other : kf->covisiblesWithWeightAtLeast(min_covisibility_weight)) {
      if (claim(kf->id(), other)) {
        const auto [low, high] = ordered(kf->id(), other);
        edges.push_back({low, high, EdgeKind::kCovisibility, kf->weight(other)});
      }
    }
  }
  std::sort(edges.begin(), edges.end(), [](const EssentialEdge& a, const EssentialEdge& b) {
    return std::make_tuple(static_cast<int>(a.kind), a.from, a.to) <
           std::make_tuple(static_cast<int>(b.kind), b.from, b.to);
  });
  return edges;
}

}  // namespace ltlo::map
