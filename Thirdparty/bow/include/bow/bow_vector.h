#pragma once
/// Bag-of-words vector, direct index (feature vector) and the L1 similarity score.
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

namespace bow {

using WordId = std::uint32_t;  ///< index of a leaf of the vocabulary tree, in [0, numWords())
using NodeId = std::uint32_t;  ///< index of any node of the tree (root = 0)

/// Sparse weight vector over words, sorted by word id with unique ids; after
/// Vocabulary::transform the weights are TF-IDF and sum to 1 (L1-normalised).
struct BowVector {
  std::vector<std::pair<WordId, float>> entries;
  bool empty() const { return entries.empty(); }
  std::size_t size() const { return entries.size(); }
};

/// Direct index: node id at a chosen tree depth -> indices of the features that fell under it.
/// Guided matching compares only features that share a node.
using FeatureVector = std::map<NodeId, std::vector<std::uint32_t>>;

/// L1 similarity of two L1-normalised vectors: 1 - 0.5 * |a - b|_1, in [0, 1] (1 = identical).
double l1Score(const BowVector& a, const BowVector& b);

}  // namespace bow
