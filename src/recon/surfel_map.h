#pragma once
// Surfel storage in cubic cells of a hash grid, so that a frame touches only the cells inside its
// view frustum. A surfel stays in the cell it was created in (fusion moves it by millimetres);
// cells are culled with a margin for that.
#include <Eigen/Core>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "ltlo/recon/surfel.h"

namespace ltlo::recon {

class SurfelMap {
 public:
  struct Cell {
    Eigen::Vector3f centre_w;
    std::vector<Surfel> surfels;
  };

  explicit SurfelMap(float cell_size_m) : cell_size_m_(cell_size_m) {}

  /// Appends `surfel` to the cell holding its position.
  void insert(const Surfel& surfel);
  /// Drops the surfels of `cell` marked removed (confidence < 0).
  static std::size_t compact(Cell* cell);

  std::vector<Cell>& cells() { return cells_; }
  const std::vector<Cell>& cells() const { return cells_; }
  float cellSizeM() const { return cell_size_m_; }
  std::size_t size() const;
  std::size_t heapBytes() const;

 private:
  float cell_size_m_;
  std::unordered_map<uint64_t, int> cell_of_key_;  // packed integer cell coordinates -> cells_
  std::vector<Cell> cells_;
};

}  // namespace ltlo::recon
