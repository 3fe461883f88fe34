#include "ltlo/loop/loop_detector.h"

#include <algorithm>
#include <limits>

#include "bow/bow_vector.h"
#include "ltlo/core/assert.h"
#include "ltlo/map/binary_io.h"

namespace ltlo::loop {

ConsistencyChecker::ConsistencyChecker(int min_consistency) : min_consistency_(min_consistency) {
  LTLO_ASSERT(min_consistency >= 1, "ConsistencyChecker: min_consistency " << min_consistency << " < 1");
}

int ConsistencyChecker::maxCount() const {
  int best = 0;
  for (const Tracked& t : previous_) best = std::max(best, t.count);
  return best;
}

std::vector<map::KeyFrameId> ConsistencyChecker::update(const std::vector<CandidateGroup>& groups) {
  std::vector<Tracked> current;
  std::vector<map::KeyFrameId> accepted;
  for (const CandidateGroup& group : groups) {
    Tracked tracked;
    tracked.members.insert(group.members.begin(), group.members.end());
    tracked.members.insert(group.candidate);
    int count = 1;
    for (const Tracked& previous : previous_) {
      const bool shares = std::any_of(tracked.members.begin(), tracked.members.end(),
                                      [&](map::KeyFrameId id) { return previous.members.count(id) > 0; });
      if (shares) count = std::max(count, previous.count + 1);
    }
    tracked.count = count;
    if (count >= min_consistency_) accepted.push_back(group.candidate);
    current.push_back(std::move(tracked));
  }
  previous_ = std::move(current);
  return accepted;
}

void ConsistencyChecker::writeState(map::ByteWriter& out) const {
  out.u64(previous_.size());
  for (const Tracked& tracked : previous_) {
    out.i32(tracked.count);
    out.u64(tracked.members.size());
    for (const map::KeyFrameId id : tracked.members) out.u64(id.value);
  }
}

void ConsistencyChecker::readState(map::ByteReader& in) {
  const std::size_t n = in.count("consistency groups", 4 + 8);
  previous_.assign(n, Tracked());
  for (Tracked& tracked : previous_) {
    tracked.count = in.i32InRange("consistency count", 1, std::numeric_limits<std::int32_t>::max());
    const std::size_t members = in.count("consistency group members", 8);
    for (std::size_t k = 0; k < members; ++k) tracked.members.insert(map::KeyFrameId(in.u64("consistency group member")));
  }
}

LoopDetector::LoopDetector(const LoopOptions& options, const map::PlaceQueryOptions& query, std::size_t group_size)
    : options_(options), query_(query), group_size_(group_size), consistency_(options.min_consistency) {}

std::vector<std::shared_ptr<map::KeyFrame>> LoopDetector::detect(const map::KeyFrame& current, const map::Map& map,
                                                                 const map::KeyFrameDatabase& database) {
  if (current.staticAreaRatio() < options_.min_static_ratio || !current.hasBow()) return {};

  map::PlaceQueryOptions query = query_;
  bool have_covisible = false;
  double min_score = 1.0;
  for (const map::KeyFrameId id : current.bestCovisibles(group_size_)) {
    const std::shared_ptr<map::KeyFrame> kf = map.keyFrame(id);
    if (!kf || kf->isBad() || !kf->hasBow()) continue;
    min_score = std::min(min_score, bow::l1Score(current.bowVector(), kf->bowVector()));
    have_covisible = true;
  }
  if (have_covisible) query.min_score = std::max(query.min_score, min_score);

  const std::vector<map::PlaceCandidate> candidates =
      database.detectLoopCandidates(current, options_.min_static_ratio, query);
  if (candidates.empty()) {
    consistency_.reset();
    return {};
  }
  std::vector<CandidateGroup> groups;
  for (const map::PlaceCandidate& candidate : candidates) {
    CandidateGroup group;
    group.candidate = candidate.keyframe->id();
    group.members = candidate.keyframe->bestCovisibles(group_size_);
    groups.push_back(std::move(group));
  }
  const std::vector<map::KeyFrameId> accepted = consistency_.update(groups);
  std::vector<std::shared_ptr<map::KeyFrame>> result;
  for (const map::PlaceCandidate& candidate : candidates) {
    if (std::find(accepted.begin(), accepted.end(), candidate.keyframe->id()) != accepted.end()) {
      result.push_back(candidate.keyframe);
    }
  }
  return result;
}

}  // namespace ltlo::loop
