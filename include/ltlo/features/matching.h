#pragma once
/// Descriptor matching helpers: Hamming distance, ratio test, rotation-consistency histogram,
/// a grid index for search by projection, and matching guided by BoW feature vectors.
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include "ltlo/features/orb_extractor.h"

namespace ltlo::features {

/// Number of differing bits of two 256-bit descriptors, in [0, 256] (hardware popcount).
inline int hammingDistance(const Descriptor& a, const Descriptor& b) {
  return __builtin_popcountll(a[0] ^ b[0]) + __builtin_popcountll(a[1] ^ b[1]) +
         __builtin_popcountll(a[2] ^ b[2]) + __builtin_popcountll(a[3] ^ b[3]);
}

/// Lowe's ratio test on distances: the best must be clearly better than the second best.
inline bool passesRatioTest(int best_distance, int second_distance, double max_ratio) {
  return static_cast<double>(best_distance) < max_ratio * static_cast<double>(second_distance);
}

struct Match {
  int query = -1;     ///< index in the first (query) feature set
  int train = -1;     ///< index in the second feature set
  int distance = 0;   ///< Hamming distance
};

/// Best and second-best distance of `query` among `descriptors[candidates]`.
struct NearestResult {
  int index = -1;                 ///< best candidate (index into descriptors), -1 if none
  int distance = 257;
  int second_distance = 257;
};
NearestResult findNearest(const Descriptor& query, const std::vector<Descriptor>& descriptors,
                          const std::vector<int>& candidates);

/// Histogram of rotation differences (angle_train - angle_query) in 30 bins of 12 degrees; a
/// correct set of matches between two views shares one rotation, so matches outside the three
/// most populated bins are treated as outliers (bins 2 and 3 only count if they hold >= 10% of bin 1).
class RotationHistogram {
 public:
  static constexpr int kNumBins = 30;
  void add(float angle_query_deg, float angle_train_deg, int match_index);
  /// Indices passed to add() that fall in the dominant bins, in increasing order.
  std::vector<int> consistent() const;
  /// Convenience: keeps only the rotation-consistent matches.
  static std::vector<Match> filter(const std::vector<Match>& matches, const std::vector<Keypoint>& query,
                                   const std::vector<Keypoint>& train);

 private:
  std::vector<int> bins_[kNumBins];
};

/// Grid over keypoints for search by projection: the candidates near a predicted pixel.
/// Built once per frame; keeps a pointer to `keypoints`, which must outlive it (and not change).
/// Const queries are thread-safe.
class KeypointGrid {
 public:
  /// Image size in level-0 pixels; `cell_px` is the cell side.
  KeypointGrid(const std::vector<Keypoint>& keypoints, int width_px, int height_px, float cell_px = 16.0f);
  /// Indices of keypoints within `radius_px` (Chebyshev, as a window) of (x_px, y_px) whose octave
  /// is in [min_octave, max_octave] (max_octave < 0: no upper bound).
  std::vector<int> candidates(float x_px, float y_px, float radius_px, int min_octave = 0, int max_octave = -1) const;

 private:
  const std::vector<Keypoint>* keypoints_;
  int cols_;
  int rows_;
  float inv_cell_;
  std::vector<std::vector<int>> cells_;
};

/// Feature vector as produced by bow::Vocabulary::transform (node id -> feature indices); the
/// same std::map type as bow::FeatureVector, so features does not depend on the bow library.
using NodeFeatures = std::map<std::uint32_t, std::vector<std::uint32_t>>;

struct GuidedMatchOptions {
  int max_distance = 50;           ///< accept a match only below this Hamming distance
  double ratio = 0.7;              ///< ratio test on best / second best within the node
  bool check_orientation = true;   ///< rotation-consistency histogram
};

/// Matches features of A and B that share a vocabulary node (one-to-one: each train feature
/// keeps its best query). Returned with query = index in A, train = index in B.
std::vector<Match> matchByBow(const NodeFeatures& nodes_a, const OrbFeatures& a, const NodeFeatures& nodes_b,
                              const OrbFeatures& b, const GuidedMatchOptions& options);

/// Brute-force one-to-one matching with the ratio test (reference and tests).
std::vector<Match> matchBruteForce(const OrbFeatures& a, const OrbFeatures& b, int max_distance, double ratio);

}  // namespace ltlo::features
