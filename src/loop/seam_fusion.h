#pragma once
/// Duplicate map points across a merge seam (private to ltlo_loop): after two maps are aligned at a
/// recognised place, both still hold their own points for the same static structure around it, so
/// a BA could only weld them through the few points the place match fused. This projects the
/// points of one side's keyframes into the other side's keyframes and fuses the duplicates
/// (ORB-SLAM's search-and-fuse of a merge), so the welding and full BAs see the seam everywhere
/// the two windows overlap. Works through the thread-safe Map API (loop thread, local mapping
/// paused).
#include <memory>
#include <vector>

#include "ltlo/map/keyframe.h"
#include "ltlo/map/map.h"
#include "ltlo/map/map_point.h"

namespace ltlo::loop {

struct SeamFusionOptions {
  double bf_px_m = 40.0;        ///< virtual stereo baseline of the RGB-D observations (px m)
  /// Search half window at level 0 (times the predicted level's scale): the seam is aligned only
  /// as well as one place match, so wider than local mapping's fusion (ORB-SLAM's loop fusion: 4).
  double radius_px = 4.0;
  int max_hamming = 50;         ///< of 256 bits
  double min_point_beta = 0.5;  ///< points with a lower static score are not fused
};

struct SeamFusionStats {
  int replaced = 0;  ///< duplicate pairs merged (Map::replaceMapPoint; the better observed survives)
  int linked = 0;    ///< new observations of a point by a keyframe whose keypoint had none
};

/// The live points seen by `keyframes` (each once), static score >= min_point_beta.
std::vector<std::shared_ptr<map::MapPoint>> pointsSeenBy(const map::Map& map,
                                                         const std::vector<std::shared_ptr<map::KeyFrame>>& keyframes,
                                                         double min_point_beta);

/// Projects every point of `points` into every keyframe of `targets` (not already observing it):
/// in the image, in front, within its scale-invariance distances, seen within 60 deg of its mean
/// viewing direction; the static keypoint at the predicted level within the radius that passes the
/// chi-square gate on [u, v, u_r] (1 px per level) with the smallest Hamming distance (<=
/// max_hamming) takes it: merged with the point it holds, or linked. Then refreshes descriptors,
/// normals and the targets' covisibility.
SeamFusionStats fuseAcrossSeam(map::Map& map, const std::vector<std::shared_ptr<map::KeyFrame>>& targets,
                               const std::vector<std::shared_ptr<map::MapPoint>>& points,
                               const SeamFusionOptions& options);

}  // namespace ltlo::loop
