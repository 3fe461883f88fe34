#include "ltlo/map/keyframe_database.h"

#include <algorithm>
#include <unordered_set>

#include "ltlo/core/assert.h"

namespace ltlo::map {

namespace {
int commonWords(const bow::BowVector& a, const bow::BowVector& b) {
  int common = 0;
  auto ia = a.entries.begin();
  auto ib = b.entries.begin();
  while (ia != a.entries.end() && ib != b.entries.end()) {
    if (ia->first == ib->first) {
      ++common;
      ++ia;
      ++ib;
    } else if (ia->first < ib->first) {
      ++ia;
    } else {
      ++ib;
    }
  }
  return common;
}

struct Scored {
  std::shared_ptr<KeyFrame> kf;
  double score;
  int common_words;
};
}  // namespace

KeyFrameDatabase::KeyFrameDatabase(std::size_t num_words) : database_(num_words) {}

void KeyFrameDatabase::add(const std::shared_ptr<KeyFrame>& kf) {
  LTLO_ASSERT(kf && kf->hasBow(), "keyframe database: keyframe without a BoW vector");
  std::lock_guard<std::mutex> lock(mutex_);
  if (entry_of_.count(kf->id()) > 0) return;
  const bow::EntryId entry = database_.add(kf->bowVector());
  entry_of_.emplace(kf->id(), entry);
  keyframe_of_.emplace(entry, kf);
}

bool KeyFrameDatabase::erase(KeyFrameId id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = entry_of_.find(id);
  if (it == entry_of_.end()) return false;
  database_.remove(it->second);
  keyframe_of_.erase(it->second);
  entry_of_.erase(it);
  return true;
}

bool KeyFrameDatabase::replace(const std::shared_ptr<KeyFrame>& kf) {
  if (!kf || !kf->hasBow()) return false;
  const bow::BowVector bow_vector = kf->bowVector();  // the keyframe's lock, before ours
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = entry_of_.find(kf->id());
  if (it == entry_of_.end()) return false;
  database_.remove(it->second);
  keyframe_of_.erase(it->second);
  const bow::EntryId entry = database_.add(bow_vector);
  it->second = entry;
  keyframe_of_.emplace(entry, kf);
  return true;
}

std::size_t KeyFrameDatabase::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return entry_of_.size();
}

std::vector<KeyFrameId> KeyFrameDatabase::keyFrameIdsInOrder() const {
  std::vector<std::pair<bow::EntryId, KeyFrameId>> entries;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    entries.reserve(entry_of_.size());
    for (const auto& [id, entry] : entry_of_) entries.emplace_back(entry, id);
  }
  std::sort(entries.begin(), entries.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });  // entry ids grow with each add
  std::vector<KeyFrameId> ids;
  ids.reserve(entries.size());
  for (const auto& [entry, id] : entries) ids.push_back(id);
  return ids;
}

void KeyFrameDatabase::clear() {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& [id, entry] : entry_of_) database_.remove(entry);
  entry_of_.clear();
  keyframe_of_.clear();
}

std::vector<PlaceCandidate> KeyFrameDatabase::detectCandidates(const bow::BowVector& query, const Filter& accept,
                                                               const PlaceQueryOptions& options) const {
  // 1. Every keyframe sharing a word with the query, scored; copied out so the predicates (which
  //    take keyframe locks) run without the database lock.
  std::vector<Scored> sharing;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const bow::QueryResult& result : database_.query(query, database_.size())) {
      std::shared_ptr<KeyFrame> kf = keyframe_of_.at(result.entry).lock();
      if (!kf) continue;
      sharing.push_back({std::move(kf), result.score, commonWords(query, *database_.entry(result.entry))});
    }
  }
  sharing.erase(std::remove_if(sharing.begin(), sharing.end(),
                               [&](const Scored& s) { return s.kf->isBad() || (accept && !accept(*s.kf)); }),
                sharing.end());
  if (sharing.empty()) return {};

  // 2. Keep those sharing nearly as many words as the best and scoring above min_score.
  int max_common = 0;
  for (const Scored& s : sharing) max_common = std::max(max_common, s.common_words);
  const double min_common = options.min_common_words_ratio * max_common;
  std::unordered_map<KeyFrameId, const Scored*> kept;
  for (const Scored& s : sharing) {
    if (s.common_words > min_common && s.score >= options.min_score) kept.emplace(s.kf->id(), &s);
  }

  // 3. Accumulate each candidate's score over its best covisibles that were kept too; the group is
  //    represented by its best-scoring member.
  struct Group {
    const Scored* best;
    double score;
  };
  std::vector<Group> groups;
  double best_group_score = 0.0;
  for (const Scored& s : sharing) {
    if (kept.count(s.kf->id()) == 0) continue;
    Group group{&s, s.score};
    for (KeyFrameId neighbour : s.kf->bestCovisibles(options.group_size)) {
      const auto it = kept.find(neighbour);
      if (it == kept.end()) continue;
      group.score += it->second->score;
      if (it->second->score > group.best->score) group.best = it->second;
    }
    best_group_score = std::max(best_group_score, group.score);
    groups.push_back(group);
  }
  std::sort(groups.begin(), groups.end(), [](const Group& a, const Group& b) {
    return a.score != b.score ? a.score > b.score : a.best->kf->id() < b.best->kf->id();
  });
  std::vector<PlaceCandidate> candidates;
  std::unordered_set<KeyFrameId> returned;
  for (const Group& group : groups) {
    if (group.score < options.min_group_score_ratio * best_group_score) break;
    if (!returned.insert(group.best->kf->id()).second) continue;
    candidates.push_back({group.best->kf, group.best->score, group.score, group.best->common_words});
  }
  return candidates;
}

std::vector<PlaceCandidate> KeyFrameDatabase::detectLoopCandidates(const KeyFrame& query, double min_static_ratio,
                                                                   const PlaceQueryOptions& options) const {
  const MapId map = query.mapId();
  std::unordered_set<KeyFrameId> excluded{query.id()};
  for (const auto& [id, w] : query.covisibles()) excluded.insert(id);
  return detectCandidates(
      query.bowVector(),
      [&](const KeyFrame& kf) {
        return kf.mapId() == map && excluded.count(kf.id()) == 0 && kf.staticAreaRatio() >= min_static_ratio;
      },
      options);
}

std::vector<PlaceCandidate> KeyFrameDatabase::detectMergeCandidates(const KeyFrame& query, double min_static_ratio,
                                                                    const PlaceQueryOptions& options) const {
  const MapId map = query.mapId();
  return detectCandidates(
      query.bowVector(),
      [&](const KeyFrame& kf) { return kf.mapId() != map && kf.staticAreaRatio() >= min_static_ratio; }, options);
}

std::vector<PlaceCandidate> KeyFrameDatabase::detectRelocalisationCandidates(const Frame& frame, MapId map,
                                                                             const PlaceQueryOptions& options) const {
  LTLO_ASSERT(frame.hasBow(), "relocalisation query at t = " << frame.t_s() << " s without a BoW vector");
  return detectCandidates(
      frame.bowVector(), [&](const KeyFrame& kf) { return kf.mapId() == map; }, options);
}

}  // namespace ltlo::map
