#pragma once
/// Place recognition over keyframes on the bow inverted file: candidates for loop closing, map
/// merging and relocalisation (shared-word filter, then covisibility-group score accumulation).
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "bow/bow_vector.h"
#include "bow/database.h"
#include "ltlo/map/frame.h"
#include "ltlo/map/ids.h"
#include "ltlo/map/keyframe.h"

namespace ltlo::map {

struct PlaceCandidate {
  std::shared_ptr<KeyFrame> keyframe;  ///< best-scoring keyframe of its covisibility group
  double score = 0.0;                  ///< its own L1 BoW score against the query, [0, 1]
  double group_score = 0.0;            ///< score accumulated over its group
  int common_words = 0;                ///< words shared with the query
};

/// Tunables of the candidate search.
struct PlaceQueryOptions {
  double min_score = 0.0;               ///< candidates must score at least this (loop: min over covisibles)
  double min_common_words_ratio = 0.8;  ///< keep keyframes sharing > ratio * the most shared words
  double min_group_score_ratio = 0.75;  ///< keep groups scoring >= ratio * the best group
  std::size_t group_size = 10;          ///< best covisibles forming a candidate's group
};

/// Thread-safe: mutex_ guards the inverted file and the entry table; it is taken alone (never
/// while holding, or while taking, another lock of atlas.h's order): keyframe predicates run
/// after it is released. Holds weak_ptr only: a culled keyframe stays until erase() but is
/// never returned once bad. Written by local mapping (add) and culling (erase), queried by loop
/// closing and tracking (relocalisation).
class KeyFrameDatabase {
 public:
  /// `num_words` is the vocabulary's numWords().
  explicit KeyFrameDatabase(std::size_t num_words);

  /// Adds a keyframe with a BoW vector (asserts hasBow()). Adding an id twice is a no-op.
  void add(const std::shared_ptr<KeyFrame>& kf);
  /// Returns false if the keyframe was not in the database.
  bool erase(KeyFrameId id);
  /// A keyframe's BoW changed (local mapping refined its Gamma, so its static features changed):
  /// its entry is removed and re-added with the current BoW vector in one step under the lock
  /// (queries never miss it). No-op returning false when it is not in the database (loop closing
  /// adds it later with the new vector) or has no BoW.
  bool replace(const std::shared_ptr<KeyFrame>& kf);
  std::size_t size() const;
  /// The keyframes in the database in the order they were (last) added: queries break ties between
  /// equal scores by it, so a resumed run rebuilds the database in this order (run_state_io.h).
  std::vector<KeyFrameId> keyFrameIdsInOrder() const;
  /// Empties the database (before a restored one is rebuilt in its saved order).
  void clear();

  using Filter = std::function<bool(const KeyFrame&)>;
  /// Candidates for `query` among keyframes passing `accept`, best group first.
  std::vector<PlaceCandidate> detectCandidates(const bow::BowVector& query, const Filter& accept,
                                               const PlaceQueryOptions& options) const;
  /// Loop closing: same map, not `query` nor covisible with it, static area ratio >= min_static_ratio.
  std::vector<PlaceCandidate> detectLoopCandidates(const KeyFrame& query, double min_static_ratio,
                                                   const PlaceQueryOptions& options) const;
  /// Map merging: keyframes of other maps with static area ratio >= min_static_ratio.
  std::vector<PlaceCandidate> detectMergeCandidates(const KeyFrame& query, double min_static_ratio,
                                                    const PlaceQueryOptions& options) const;
  /// Relocalisation of a lost frame (with its BoW computed): keyframes of map `map`.
  std::vector<PlaceCandidate> detectRelocalisationCandidates(const Frame& frame, MapId map,
                                                             const PlaceQueryOptions& options) const;

 private:
  mutable std::mutex mutex_;
  bow::Database database_;
  std::unordered_map<KeyFrameId, bow::EntryId> entry_of_;
  std::unordered_map<bow::EntryId, std::weak_ptr<KeyFrame>> keyframe_of_;
};

}  // namespace ltlo::map
