#pragma once
/// Inverted-file image database: add/remove BoW vectors, query the top-N by L1 score.
#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

#include "bow/bow_vector.h"

namespace bow {

using EntryId = std::uint32_t;  ///< returned by Database::add, never reused

struct QueryResult {
  EntryId entry = 0;
  double score = 0.0;  ///< L1 score in [0, 1]
};

/// Not thread-safe: the owner serialises calls (e.g. under its own mutex).
class Database {
 public:
  /// `num_words` is Vocabulary::numWords(); word ids of added vectors must be below it.
  explicit Database(std::size_t num_words);

  EntryId add(const BowVector& bow_vector);
  /// Returns false when the entry is unknown (already removed or never added).
  bool remove(EntryId entry);
  std::size_t size() const { return entries_.size(); }
  const BowVector* entry(EntryId entry) const;

  /// Best `max_results` entries by L1 score, best first (ties by lower id); entries with no word
  /// in common are never returned. If `accept` is set, only entries with accept(id) == true count.
  std::vector<QueryResult> query(const BowVector& query, std::size_t max_results,
                                 const std::function<bool(EntryId)>& accept = {}) const;

 private:
  struct Posting {
    EntryId entry;
    float weight;
  };
  std::vector<std::vector<Posting>> inverted_;  ///< word -> entries containing it
  std::unordered_map<EntryId, BowVector> entries_;
  EntryId next_id_ = 0;
};

}  // namespace bow
