#pragma once
/// Map maintenance of local mapping (private to ltlo_mapping): culling of recently created map
/// points that tracking does not confirm, and of redundant keyframes (ORB-SLAM's MapPointCulling
/// and KeyFrameCulling, with the static-score rule of DESIGN.md and the IMU time-span rule).
#include <deque>
#include <vector>

#include "ltlo/map/atlas.h"
#include "ltlo/map/binary_io.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/map.h"

namespace ltlo::mapping {

/// The points created by the last keyframes, checked at each new keyframe until they are old
/// enough. Owned by the mapping thread (not thread-safe).
class RecentPointCuller {
 public:
  struct Options {
    double min_found_ratio = 0.25;  ///< found / visible in tracking below this: culled
    int min_observations = 2;       ///< keyframes seeing it once min_age keyframes passed
    int min_age = 2;                ///< keyframes since creation before the observation test
    int mature_age = 3;             ///< keyframes since creation after which it is no longer checked
    double min_point_beta = 0.5;    ///< static score below this: culled as dynamic
  };
  explicit RecentPointCuller(const Options& options) : options_(options) {}

  /// Remembers the points `kf` created (its points whose reference keyframe it is); `sequence` is
  /// the processing index of `kf` (grows by one per keyframe).
  void addPointsOf(const map::Map& map, const map::KeyFrame& kf, int sequence);
  /// Checks the remembered points at processing index `sequence`; returns how many were erased.
  int cull(map::Atlas& atlas, int sequence);
  std::size_t size() const { return entries_.size(); }
  /// The remembered points (a run resumed from an atlas file, LocalMapper::writeState).
  void writeState(map::ByteWriter& out) const;
  void readState(map::ByteReader& in);

 private:
  struct Entry {
    map::MapId map;
    map::MapPointId point;
    int created_at = 0;
  };
  Options options_;
  std::deque<Entry> entries_;
};

/// Erases the points of `kf` whose static score beta is below `min_point_beta`; returns the count.
int cullDynamicPoints(map::Map& map, const map::KeyFrame& kf, double min_point_beta);

struct KeyFrameCullingOptions {
  double redundant_ratio = 0.9;     ///< share of a keyframe's points seen elsewhere to cull it
  int min_other_observers = 3;      ///< a point is redundant when this many other keyframes see it
  std::size_t min_map_keyframes = 5;   ///< no culling in maps with this many keyframes or fewer
  std::size_t max_candidates = 20;     ///< best covisibles of the current keyframe examined
  /// With the IMU: keep a keyframe whose neighbours in time are further apart than this (s), so
  /// the merged preintegration stays short (ORB-SLAM3's rule).
  bool use_imu = true;
  double max_imu_span_s = 0.5;
  /// With the IMU: a keyframe this much older than the current one (s), whose next keyframe is as
  /// old, is culled even when its neighbours are further apart than max_imu_span_s; the chain is
  /// then cut there (Map::ImuLink::kCut) rather than bridged by an ever longer preintegration. The
  /// recent chain (local BA's inertial window, IMU refinements) keeps its links. 0: never.
  double cut_imu_min_age_s = 0.0;
};

/// Whether at least `ratio` of `kf`'s points with depth are seen by min_other_observers other
/// keyframes at the same or a finer scale (octave at most one above); false without such points.
bool mostlyRedundant(const map::Map& map, const map::KeyFrame& kf, int min_other_observers, double ratio);

/// Culls the redundant covisibles of `current` (only keyframes older than `current`, never its
/// predecessor in time or an origin keyframe): those whose points with depth are seen at the same or a finer scale by
/// min_other_observers other keyframes for at least redundant_ratio of them. Returns the culled ids;
/// `cut_links` (optional) counts the culls that cut the IMU chain.
std::vector<map::KeyFrameId> cullRedundantKeyFrames(map::Map& map, const map::KeyFrame& current,
                                                    const KeyFrameCullingOptions& options, int* cut_links = nullptr);

}  // namespace ltlo::mapping
