#include "ltlo/features/matching.h"

#include <algorithm>
#include <cmath>

namespace ltlo::features {

NearestResult findNearest(const Descriptor& query, const std::vector<Descriptor>& descriptors,
                          const std::vector<int>& candidates) {
  NearestResult result;
  for (int c : candidates) {
    const int d = hammingDistance(query, descriptors[c]);
    if (d < result.distance) {
      result.second_distance = result.distance;
      result.distance = d;
      result.index = c;
    } else if (d < result.second_distance) {
      result.second_distance = d;
    }
  }
  return result;
}

void RotationHistogram::add(float angle_query_deg, float angle_train_deg, int match_index) {
  float diff = angle_train_deg - angle_query_deg;
  diff -= 360.0f * std::floor(diff / 360.0f);
  const int bin = std::min(kNumBins - 1, static_cast<int>(diff * (kNumBins / 360.0f)));
  bins_[bin].push_back(match_index);
}

std::vector<int> RotationHistogram::consistent() const {
  int best[3] = {-1, -1, -1};
  const auto count = [this](int bin) { return bin < 0 ? 0 : static_cast<int>(bins_[bin].size()); };
  for (int b = 0; b < kNumBins; ++b) {
    if (count(b) > count(best[0])) {
      best[2] = best[1];
      best[1] = best[0];
      best[0] = b;
    } else if (count(b) > count(best[1])) {
      best[2] = best[1];
      best[1] = b;
    } else if (count(b) > count(best[2])) {
      best[2] = b;
    }
  }
  std::vector<int> kept;
  for (int rank = 0; rank < 3; ++rank) {
    if (best[rank] < 0) continue;
    if (rank > 0 && count(best[rank]) < 0.1 * count(best[0])) continue;
    kept.insert(kept.end(), bins_[best[rank]].begin(), bins_[best[rank]].end());
  }
  std::sort(kept.begin(), kept.end());
  return kept;
}

std::vector<Match> RotationHistogram::filter(const std::vector<Match>& matches, const std::vector<Keypoint>& query,
                                             const std::vector<Keypoint>& train) {
  RotationHistogram histogram;
  for (int i = 0; i < static_cast<int>(matches.size()); ++i) {
    histogram.add(query[matches[i].query].angle_deg, train[matches[i].train].angle_deg, i);
  }
  std::vector<Match> kept;
  for (int i : histogram.consistent()) kept.push_back(matches[i]);
  return kept;
}

KeypointGrid::KeypointGrid(const std::vector<Keypoint>& keypoints, int width_px, int height_px, float cell_px)
    : keypoints_(&keypoints),
      cols_(std::max(1, static_cast<int>(std::ceil(width_px / cell_px)))),
      rows_(std::max(1, static_cast<int>(std::ceil(height_px / cell_px)))),
      inv_cell_(1.0f / cell_px),
      cells_(static_cast<std::size_t>(cols_) * rows_) {
  for (int i = 0; i < static_cast<int>(keypoints.size()); ++i) {
    const int c = std::clamp(static_cast<int>(keypoints[i].x_px * inv_cell_), 0, cols_ - 1);
    const int r = std::clamp(static_cast<int>(keypoints[i].y_px * inv_cell_), 0, rows_ - 1);
    cells_[static_cast<std::size_t>(r) * cols_ + c].push_back(i);
  }
}

std::vector<int> KeypointGrid::candidates(float x_px, float y_px, float radius_px, int min_octave,
                                          int max_octave) const {
  std::vector<int> result;
  const int c0 = std::max(0, static_cast<int>(std::floor((x_px - radius_px) * inv_cell_)));
  const int c1 = std::min(cols_ - 1, static_cast<int>(std::floor((x_px + radius_px) * inv_cell_)));
  const int r0 = std::max(0, static_cast<int>(std::floor((y_px - radius_px) * inv_cell_)));
  const int r1 = std::min(rows_ - 1, static_cast<int>(std::floor((y_px + radius_px) * inv_cell_)));
  for (int r = r0; r <= r1; ++r) {
    for (int c = c0; c <= c1; ++c) {
      for (int i : cells_[static_cast<std::size_t>(r) * cols_ + c]) {
        const Keypoint& kp = (*keypoints_)[i];
        if (kp.octave < min_octave || (max_octave >= 0 && kp.octave > max_octave)) continue;
        if (std::abs(kp.x_px - x_px) > radius_px || std::abs(kp.y_px - y_px) > radius_px) continue;
        result.push_back(i);
      }
    }
  }
  std::sort(result.begin(), result.end());
  return result;
}

namespace {

/// Keeps, for every train index, only the query with the smallest distance (ties: first seen).
std::vector<Match> oneToOne(const std::vector<Match>& matches, std::size_t num_train) {
  std::vector<int> best(num_train, -1);
  for (int i = 0; i < static_cast<int>(matches.size()); ++i) {
    int& slot = best[matches[i].train];
    if (slot < 0 || matches[i].distance < matches[slot].distance) slot = i;
  }
  std::vector<Match> kept;
  for (int i = 0; i < static_cast<int>(matches.size()); ++i) {
    if (best[matches[i].train] == i) kept.push_back(matches[i]);
  }
  return kept;
}

}  // namespace

std::vector<Match> matchByBow(const NodeFeatures& nodes_a, const OrbFeatures& a, const NodeFeatures& nodes_b,
                              const OrbFeatures& b, const GuidedMatchOptions& options) {
  std::vector<Match> matches;
  std::vector<int> candidates;
  auto ia = nodes_a.begin();
  auto ib = nodes_b.begin();
  while (ia != nodes_a.end() && ib != nodes_b.end()) {  // both maps are sorted by node id
    if (ia->first < ib->first) {
      ++ia;
      continue;
    }
    if (ib->first < ia->first) {
      ++ib;
      continue;
    }
    candidates.assign(ib->second.begin(), ib->second.end());
    for (std::uint32_t qa : ia->second) {
      const NearestResult nearest = findNearest(a.descriptors[qa], b.descriptors, candidates);
      if (nearest.index < 0 || nearest.distance > options.max_distance) continue;
      if (nearest.second_distance <= 256 && !passesRatioTest(nearest.distance, nearest.second_distance, options.ratio)) {
        continue;
      }
      matches.push_back({static_cast<int>(qa), nearest.index, nearest.distance});
    }
    ++ia;
    ++ib;
  }
  std::sort(matches.begin(), matches.end(), [](const Match& x, const Match& y) { return x.query < y.query; });
  matches = oneToOne(matches, b.descriptors.size());
  if (options.check_orientation) matches = RotationHistogram::filter(matches, a.keypoints, b.keypoints);
  return matches;
}

std::vector<Match> matchBruteForce(const OrbFeatures& a, const OrbFeatures& b, int max_distance, double ratio) {
  std::vector<int> all(b.descriptors.size());
  for (int i = 0; i < static_cast<int>(all.size()); ++i) all[i] = i;
  std::vector<Match> matches;
  for (int q = 0; q < static_cast<int>(a.descriptors.size()); ++q) {
    const NearestResult nearest = findNearest(a.descriptors[q], b.descriptors, all);
    if (nearest.index < 0 || nearest.distance > max_distance) continue;
    if (!passesRatioTest(nearest.distance, nearest.second_distance, ratio)) continue;
    matches.push_back({q, nearest.index, nearest.distance});
  }
  return oneToOne(matches, b.descriptors.size());
}

}  // namespace ltlo::features
