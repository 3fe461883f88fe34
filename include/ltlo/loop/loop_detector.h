#pragma once
/// Loop candidates (namespace ltlo::loop): BoW place recognition on the keyframe database filtered by
/// covisibility consistency over consecutive queries (a place must be recognised by
/// LoopOptions::min_consistency consecutive keyframes before it is verified geometrically).
#include <memory>
#include <set>
#include <vector>

#include "ltlo/core/settings.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/keyframe_database.h"
#include "ltlo/map/map.h"

namespace ltlo::map {
class ByteReader;
class ByteWriter;
}  // namespace ltlo::map

namespace ltlo::loop {

/// A candidate keyframe and the keyframes forming its group (itself and its covisibles).
struct CandidateGroup {
  map::KeyFrameId candidate;
  std::vector<map::KeyFrameId> members;
};

/// Covisibility consistency (pure, no map access). A group is consistent with a group of the
/// previous query when they share a keyframe; its count is then the previous count + 1 (1 for a
/// first sighting). A candidate is accepted once its count reaches min_consistency. Owned by the
/// loop-closing thread; not thread-safe.
class ConsistencyChecker {
 public:
  explicit ConsistencyChecker(int min_consistency);
  /// Feeds the candidate groups of one query; returns the accepted candidates (in input order).
  std::vector<map::KeyFrameId> update(const std::vector<CandidateGroup>& groups);
  /// Forgets all groups (a query without candidates, a map change).
  void reset() { previous_.clear(); }
  /// Highest count among the groups kept from the last query (0 when none).
  int maxCount() const;
  /// The groups kept from the last query (a run resumed from an atlas file, LoopCloser::writeState).
  void writeState(map::ByteWriter& out) const;
  void readState(map::ByteReader& in);

 private:
  struct Tracked {
    std::set<map::KeyFrameId> members;
    int count = 0;
  };
  int min_consistency_;
  std::vector<Tracked> previous_;
};

/// Candidates for one keyframe from the database, then the consistency check. Owned by the
/// loop-closing thread; not thread-safe (the database and keyframes it reads are).
class LoopDetector {
 public:
  explicit LoopDetector(const LoopOptions& options, const map::PlaceQueryOptions& query = map::PlaceQueryOptions(),
                        std::size_t group_size = 10);
  /// Consistent loop candidates for `current` (best first). Keyframes with a static area ratio below
  /// Loop.MinStaticRatio are not queried (returns empty, keeps the consistency state). The BoW
  /// score threshold is the lowest score of `current` against its covisibles (ORB-SLAM's rule) when
  /// it has any, else PlaceQueryOptions::min_score.
  std::vector<std::shared_ptr<map::KeyFrame>> detect(const map::KeyFrame& current, const map::Map& map,
                                                     const map::KeyFrameDatabase& database);
  const ConsistencyChecker& consistency() const { return consistency_; }
  /// The consistency state (a run resumed from an atlas file).
  void writeState(map::ByteWriter& out) const { consistency_.writeState(out); }
  void readState(map::ByteReader& in) { consistency_.readState(in); }

 private:
  LoopOptions options_;
  map::PlaceQueryOptions query_;
  std::size_t group_size_;
  ConsistencyChecker consistency_;
};

}  // namespace ltlo::loop
