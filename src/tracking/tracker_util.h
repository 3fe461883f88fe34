#pragma once
// Small helpers shared by the Tracker's source files (private to ltlo_tracking).
#include <algorithm>

#include "ltlo/map/frame.h"

namespace ltlo::tracking::detail {

inline bool isMatched(const map::Frame& frame, int i) {
  const auto k = static_cast<std::size_t>(i);
  return frame.map_points[k].valid() && !frame.outliers[k];
}

inline int staticKeypointsWithDepth(const map::Frame& frame) {
  int with_depth = 0;
  for (const int i : frame.staticKeypoints()) {
    if (frame.depth_m(i) > 0.0f) ++with_depth;
  }
  return with_depth;
}

inline void clearMatches(map::Frame& frame) {
  std::fill(frame.map_points.begin(), frame.map_points.end(), map::MapPointId());
  std::fill(frame.outliers.begin(), frame.outliers.end(), false);
}

}  // namespace ltlo::tracking::detail
