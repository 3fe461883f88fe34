#pragma once
/// Duplicate map-point fusion by projection between a new keyframe and its covisible neighbours
/// (ORB-SLAM's SearchInNeighbors / Fuse adapted to RGB-D and to the static-only seam). Private to
/// ltlo_mapping; runs in the local-mapping thread and goes through the thread-safe Map API.
#include <memory>
#include <vector>

#include "ltlo/map/keyframe.h"
#include "ltlo/map/map.h"
#include "ltlo/map/map_point.h"

namespace ltlo::mapping {

struct FusionOptions {
  double bf_px_m = 40.0;       ///< virtual stereo baseline of the RGB-D observations (px m)
  int max_hamming = 50;        ///< accept a keypoint only below this Hamming distance (of 256)
  double radius_px = 3.0;      ///< search half window at level 0 (times the predicted scale)
  double min_point_beta = 0.5; ///< points with a lower static score are not fused
  std::size_t first_neighbours = 10;   ///< best covisibles of the keyframe
  std::size_t second_neighbours = 5;   ///< best covisibles of each of those
  std::size_t max_neighbours = 20;     ///< neighbour keyframes at most
};

struct FusionStats {
  int replaced = 0;  ///< duplicates merged (Map::replaceMapPoint)
  int linked = 0;    ///< new observations of an existing point (Map::addObservation)
  FusionStats& operator+=(const FusionStats& other) {
    replaced += other.replaced;
    linked += other.linked;
    return *this;
  }
};

/// Projects `points` into `target` and, for each one landing on a static keypoint with a similar
/// descriptor at the predicted scale and a consistent depth (chi-square test on [u, v, u_r]):
/// links the point there, or merges it with the point the keypoint already holds (the one with more
/// observations survives). `level_sigma2` is OrbExtractor::levelSigma2().
FusionStats fusePointsInto(map::Map& map, map::KeyFrame& target,
                           const std::vector<std::shared_ptr<map::MapPoint>>& points,
                           const FusionOptions& options, const std::vector<float>& level_sigma2);

/// The keyframe's neighbours (best covisibles and their best covisibles, live, of `kf`'s map).
std::vector<std::shared_ptr<map::KeyFrame>> fusionNeighbours(const map::Map& map, const map::KeyFrame& kf,
                                                             const FusionOptions& options);

/// Fuses `kf`'s points into its neighbours and theirs into `kf`, refreshes the descriptors and
/// normals of `kf`'s points and its covisibility edges.
FusionStats fuseWithNeighbours(map::Map& map, map::KeyFrame& kf, const FusionOptions& options,
                               const std::vector<float>& level_sigma2);

}  // namespace ltlo::mapping
