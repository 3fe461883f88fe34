#include "ltlo/map/grid_index.h"

#include <algorithm>
#include <cmath>

namespace ltlo::map {

GridIndex::GridIndex(const std::vector<features::Keypoint>& keypoints, int width_px, int height_px, float cell_px)
    : cols_(std::max(1, static_cast<int>(std::ceil(width_px / cell_px)))),
      rows_(std::max(1, static_cast<int>(std::ceil(height_px / cell_px)))),
      inv_cell_(1.0f / cell_px) {
  if (keypoints.empty()) return;
  // Counting sort by cell: counts, their prefix sums, then the indices in increasing order.
  const auto cellOf = [&](const features::Keypoint& kp) {
    const int col = std::clamp(static_cast<int>(kp.x_px * inv_cell_), 0, cols_ - 1);
    const int row = std::clamp(static_cast<int>(kp.y_px * inv_cell_), 0, rows_ - 1);
    return static_cast<std::size_t>(row * cols_ + col);
  };
  cell_start_.assign(static_cast<std::size_t>(cols_ * rows_) + 1, 0);
  for (const features::Keypoint& kp : keypoints) ++cell_start_[cellOf(kp) + 1];
  // Running sums: cell_start_[c + 1] is where cell c ends. Filled from the last keypoint back through
  // it, each cell ends up in increasing index order and cell_start_[c + 1] at cell c's start; one
  // shift then puts the starts in place (cell_start_[c]) and the total last.
  for (std::size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  cell_items_.resize(keypoints.size());
  for (std::size_t i = keypoints.size(); i-- > 0;) {
    cell_items_[static_cast<std::size_t>(--cell_start_[cellOf(keypoints[i]) + 1])] = static_cast<int>(i);
  }
  std::copy(cell_start_.begin() + 1, cell_start_.end(), cell_start_.begin());
  cell_start_.back() = static_cast<int>(keypoints.size());
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
  if (cell_items_.empty()) return;
  const int col_min = std::max(0, static_cast<int>(std::floor((x_px - radius_px) * inv_cell_)));
  const int col_max = std::min(cols_ - 1, static_cast<int>(std::floor((x_px + radius_px) * inv_cell_)));
  const int row_min = std::max(0, static_cast<int>(std::floor((y_px - radius_px) * inv_cell_)));
  const int row_max = std::min(rows_ - 1, static_cast<int>(std::floor((y_px + radius_px) * inv_cell_)));
  for (int row = row_min; row <= row_max; ++row) {
    for (int col = col_min; col <= col_max; ++col) {
      const std::size_t cell = static_cast<std::size_t>(row * cols_ + col);
      for (int k = cell_start_[cell]; k < cell_start_[cell + 1]; ++k) {
        const int i = cell_items_[static_cast<std::size_t>(k)];
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
