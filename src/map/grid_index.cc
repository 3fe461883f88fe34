#include "ltlo/map/grid_index.h"

#include <algorithm>
#include <cmath>

namespace ltlo::map {

GridIndex::GridIndex(const std::vector<features::Keypoint>& keypoints, int width_px, int height_px, float cell_px)
    : cols_(std::max(1, static_cast<int>(std::ceil(width_px / cell_px)))),
      rows_(std::max(1, static_cast<int>(std::ceil(height_px / cell_px)))),
      inv_cell_(1.0f / cell_px),
      cells_(static_cast<std::size_t>(cols_ * rows_)) {
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    const int col = std::clamp(static_cast<int>(keypoints[i].x_px * inv_cell_), 0, cols_ - 1);
    const int row = std::clamp(static_cast<int>(keypoints[i].y_px * inv_cell_), 0, rows_ - 1);
    cells_[static_cast<std::size_t>(row * cols_ + col)].push_back(static_cast<int>(i));
  }
}

std::vector<int> GridIndex::featuresInArea(const std::vector<features::Keypoint>& keypoints, float x_px, float y_px,
                                           float radius_px, int min_octave, int max_octave) const {
  std::vector<int> found;
  featuresInArea(keypoints, x_px, y_px, radius_px, min_octave, max_octave, &found);
  return found;
}

void GridIndex::featuresInArea(const std::vector<features::Keypoint>& keypoints, float x_px, float y_px,
                               float radius_px, int min_octave, int max_octave, std::vector<int>* found) const {
  found->clear();
  if (cells_.empty()) return;
  const int col_min = std::max(0, static_cast<int>(std::floor((x_px - radius_px) * inv_cell_)));
  const int col_max = std::min(cols_ - 1, static_cast<int>(std::floor((x_px + radius_px) * inv_cell_)));
  const int row_min = std::max(0, static_cast<int>(std::floor((y_px - radius_px) * inv_cell_)));
  const int row_max = std::min(rows_ - 1, static_cast<int>(std::floor((y_px + radius_px) * inv_cell_)));
  for (int row = row_min; row <= row_max; ++row) {
    for (int col = col_min; col <= col_max; ++col) {
      for (int i : cells_[static_cast<std::size_t>(row * cols_ + col)]) {
        const features::Keypoint& kp = keypoints[static_cast<std::size_t>(i)];
        if (kp.octave < min_octave || (max_octave >= 0 && kp.octave > max_octave)) continue;
        if (std::abs(kp.x_px - x_px) > radius_px || std::abs(kp.y_px - y_px) > radius_px) continue;
        found->push_back(i);
      }
    }
  }
  std::sort(found->begin(), found->end());
}

}  // namespace ltlo::map
