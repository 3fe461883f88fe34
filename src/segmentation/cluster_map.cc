#include "ltlo/segmentation/cluster_map.h"

#include <cmath>

#include "ltlo/core/assert.h"

namespace ltlo::segmentation {

int ClusterMap::labelAt(int u, int v) const {
  LTLO_ASSERT(u >= 0 && v >= 0 && u < labels.cols && v < labels.rows,
              "pixel (" << u << ", " << v << ") outside the " << labels.cols << "x" << labels.rows
                        << " label image");
  return labels.at<int>(v, u);
}

int ClusterMap::labelAt(const Vec2& u_px) const {
  return labelAt(static_cast<int>(std::lround(u_px.x())), static_cast<int>(std::lround(u_px.y())));
}

bool ClusterMap::connected(int a, int b) const {
  if (a > b) std::swap(a, b);
  for (const ClusterEdge& edge : edges) {
    if (edge.a == a && edge.b == b) return true;
  }
  return false;
}

std::vector<int> ClusterMap::neighbours(int k) const {
  std::vector<int> result;
  for (const ClusterEdge& edge : edges) {
    if (edge.a == k) result.push_back(edge.b);
    if (edge.b == k) result.push_back(edge.a);
  }
  return result;
}

}  // namespace ltlo::segmentation
