#include "bow/database.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace bow {

Database::Database(std::size_t num_words) : inverted_(num_words) {}

EntryId Database::add(const BowVector& bow_vector) {
  for (const auto& [word, weight] : bow_vector.entries) {
    if (word >= inverted_.size()) {
      throw std::invalid_argument("bow::Database::add: word id " + std::to_string(word) +
                                  " >= vocabulary size " + std::to_string(inverted_.size()));
    }
  }
  const EntryId id = next_id_++;
  for (const auto& [word, weight] : bow_vector.entries) inverted_[word].push_back({id, weight});
  entries_.emplace(id, bow_vector);
  return id;
}

bool Database::remove(EntryId entry) {
  const auto it = entries_.find(entry);
  if (it == entries_.end()) return false;
  for (const auto& [word, weight] : it->second.entries) {
    std::vector<Posting>& postings = inverted_[word];
    postings.erase(std::remove_if(postings.begin(), postings.end(),
                                  [entry](const Posting& p) { return p.entry == entry; }),
                   postings.end());
  }
  entries_.erase(it);
  return true;
}

const BowVector* Database::entry(EntryId entry) const {
  const auto it = entries_.find(entry);
  return it == entries_.end() ? nullptr : &it->second;
}

std::vector<QueryResult> Database::query(const BowVector& query, std::size_t max_results,
                                         const std::function<bool(EntryId)>& accept) const {
  // L1 score of normalised vectors = sum over shared words of min(q_w, d_w) (see l1Score), so
  // walking the inverted lists of the query's words accumulates the exact score of every entry.
  std::vector<float> scores(next_id_, 0.0f);
  std::vector<char> seen(next_id_, 0);
  std::vector<EntryId> touched;
  for (const auto& [word, q_weight] : query.entries) {
    if (word >= inverted_.size()) continue;
    for (const Posting& p : inverted_[word]) {
      if (!seen[p.entry]) {
        seen[p.entry] = 1;
        touched.push_back(p.entry);
      }
      scores[p.entry] += std::min(q_weight, p.weight);
    }
  }
  std::vector<QueryResult> results;
  results.reserve(touched.size());
  for (EntryId id : touched) {
    if (scores[id] <= 0.0f) continue;
    if (accept && !accept(id)) continue;
    results.push_back({id, scores[id]});
  }
  const auto better = [](const QueryResult& a, const QueryResult& b) {
    return a.score > b.score || (a.score == b.score && a.entry < b.entry);
  };
  if (results.size() > max_results) {
    std::partial_sort(results.begin(), results.begin() + static_cast<std::ptrdiff_t>(max_results),
                      results.end(), better);
    results.resize(max_results);
  } else {
    std::sort(results.begin(), results.end(), better);
  }
  return results;
}

}  // namespace bow
