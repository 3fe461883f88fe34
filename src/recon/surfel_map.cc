#include "surfel_map.h"

#include <algorithm>
#include <cmath>

namespace ltlo::recon {

void SurfelMap::insert(const Surfel& surfel) {
  const Eigen::Vector3f scaled = surfel.position_w / cell_size_m_;
  // 21 bits per axis: +-1 M cells, i.e. +-100 km with 10 cm cells.
  const int64_t x = static_cast<int64_t>(std::floor(scaled.x()));
  const int64_t y = static_cast<int64_t>(std::floor(scaled.y()));
  const int64_t z = static_cast<int64_t>(std::floor(scaled.z()));
  const uint64_t mask = (uint64_t{1} << 21) - 1;
  const uint64_t key = (static_cast<uint64_t>(x) & mask) |
                       ((static_cast<uint64_t>(y) & mask) << 21) |
                       ((static_cast<uint64_t>(z) & mask) << 42);
  auto [it, inserted] = cell_of_key_.try_emplace(key, static_cast<int>(cells_.size()));
  if (inserted) {
    Cell cell;
    cell.centre_w =
        (Eigen::Vector3f(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)) +
         Eigen::Vector3f::Constant(0.5f)) *
        cell_size_m_;
    cells_.push_back(std::move(cell));
  }
  cells_[it->second].surfels.push_back(surfel);
}

std::size_t SurfelMap::compact(Cell* cell) {
  std::vector<Surfel>& s = cell->surfels;
  const std::size_t before = s.size();
  s.erase(std::remove_if(s.begin(), s.end(), [](const Surfel& x) { return x.confidence < 0.0f; }),
          s.end());
  return before - s.size();
}

std::size_t SurfelMap::size() const {
  std::size_t n = 0;
  for (const Cell& cell : cells_) n += cell.surfels.size();
  return n;
}

std::size_t SurfelMap::heapBytes() const {
  std::size_t bytes = cells_.capacity() * sizeof(Cell) + cell_of_key_.size() * 32;
  for (const Cell& cell : cells_) bytes += cell.surfels.capacity() * sizeof(Surfel);
  return bytes;
}

}  // namespace ltlo::recon
