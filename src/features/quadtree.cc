#include "quadtree.h"

#include <algorithm>
#include <numeric>

namespace ltlo::features {
namespace {

struct QuadNode {
  float x0, y0, x1, y1;  // [x0, x1) x [y0, y1), level pixels
  std::vector<int> members;
  bool splittable() const { return members.size() > 1 && x1 - x0 >= 2.0f && y1 - y0 >= 2.0f; }
};

/// Appends the non-empty quarters of `node` to `out`.
void split(const QuadNode& node, const std::vector<cv::KeyPoint>& corners, std::vector<QuadNode>* out) {
  const float xm = 0.5f * (node.x0 + node.x1);
  const float ym = 0.5f * (node.y0 + node.y1);
  QuadNode quarters[4] = {{node.x0, node.y0, xm, ym, {}},
                          {xm, node.y0, node.x1, ym, {}},
                          {node.x0, ym, xm, node.y1, {}},
                          {xm, ym, node.x1, node.y1, {}}};
  for (int index : node.members) {
    const cv::Point2f& p = corners[index].pt;
    quarters[(p.x >= xm ? 1 : 0) + (p.y >= ym ? 2 : 0)].members.push_back(index);
  }
  for (QuadNode& q : quarters) {
    if (!q.members.empty()) out->push_back(std::move(q));
  }
}

}  // namespace

std::vector<int> selectDistributed(const std::vector<cv::KeyPoint>& corners, const cv::Rect& area, int target) {
  if (target <= 0 || corners.empty()) return {};
  // Roots: square-ish columns across the area (wide images get several).
  const int num_roots = std::max(1, static_cast<int>(std::lround(static_cast<double>(area.width) / area.height)));
  const float root_w = static_cast<float>(area.width) / num_roots;
  std::vector<QuadNode> nodes;
  for (int r = 0; r < num_roots; ++r) {
    nodes.push_back({area.x + r * root_w, static_cast<float>(area.y), area.x + (r + 1) * root_w,
                     static_cast<float>(area.y + area.height), {}});
  }
  for (int i = 0; i < static_cast<int>(corners.size()); ++i) {
    const int r = std::clamp(static_cast<int>((corners[i].pt.x - area.x) / root_w), 0, num_roots - 1);
    nodes[r].members.push_back(i);
  }
  nodes.erase(std::remove_if(nodes.begin(), nodes.end(), [](const QuadNode& n) { return n.members.empty(); }),
              nodes.end());

  while (static_cast<int>(nodes.size()) < target) {
    std::vector<int> splittable;
    for (int i = 0; i < static_cast<int>(nodes.size()); ++i) {
      if (nodes[i].splittable()) splittable.push_back(i);
    }
    if (splittable.empty()) break;
    std::vector<QuadNode> next;
    if (static_cast<int>(nodes.size() + 3 * splittable.size()) <= target) {
      for (int i = 0; i < static_cast<int>(nodes.size()); ++i) {
        if (nodes[i].splittable()) {
          split(nodes[i], corners, &next);
        } else {
          next.push_back(std::move(nodes[i]));
        }
      }
      nodes = std::move(next);
      continue;
    }
    // Last round: split the most crowded nodes first, only until the target is reached.
    std::stable_sort(splittable.begin(), splittable.end(),
                     [&](int a, int b) { return nodes[a].members.size() > nodes[b].members.size(); });
    std::vector<char> do_split(nodes.size(), 0);
    int count = static_cast<int>(nodes.size());
    for (int i : splittable) {
      if (count >= target) break;
      do_split[i] = 1;
      count += 3;  // upper bound; empty quarters are dropped
    }
    for (int i = 0; i < static_cast<int>(nodes.size()); ++i) {
      if (do_split[i]) {
        split(nodes[i], corners, &next);
      } else {
        next.push_back(std::move(nodes[i]));
      }
    }
    nodes = std::move(next);
    break;
  }

  std::vector<int> best;
  best.reserve(nodes.size());
  for (const QuadNode& node : nodes) {
    int strongest = node.members.front();
    for (int index : node.members) {
      if (corners[index].response > corners[strongest].response) strongest = index;
    }
    best.push_back(strongest);
  }
  if (static_cast<int>(best.size()) > target) {
    std::stable_sort(best.begin(), best.end(),
                     [&](int a, int b) { return corners[a].response > corners[b].response; });
    best.resize(target);
  }
  std::sort(best.begin(), best.end());
  return best;
}

}  // namespace ltlo::features
