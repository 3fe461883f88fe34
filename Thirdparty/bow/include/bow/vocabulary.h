#pragma once
/// Hierarchical k-medians vocabulary tree over 256-bit binary descriptors (k-majority on bits,
/// k-means++ seeding), with TF-IDF word weights, a compact binary file format and a text export.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "bow/bow_vector.h"
#include "bow/descriptor.h"
#include "bow/file_error.h"

namespace bow {

/// Training parameters; defaults give a 10^5-word tree.
struct TrainOptions {
  int branching = 10;          ///< k, children per node, in [2, 255]
  int depth = 5;               ///< L, levels below the root, in [1, 10]
  int max_iterations = 10;     ///< k-medians iterations per node (stops early when stable)
  std::uint64_t seed = 1;      ///< fixes seeding: same input and seed give the same tree
  int num_threads = 2;         ///< worker threads for the subtrees under the root
  /// Cluster on a deterministic random subset of at most this many descriptors (0 = all); the
  /// IDF weights always use every descriptor.
  std::size_t max_cluster_descriptors = 0;
  /// Called with one-line progress messages (may be empty); calls are serialised.
  std::function<void(const std::string&)> progress;
};

/// Immutable once built or loaded; all const methods are thread-safe.
class Vocabulary {
 public:
  Vocabulary() = default;

  /// Builds the tree from the descriptors of a set of training images (one inner vector per
  /// image; the grouping sets the IDF weights idf(w) = ln(N_images / N_images_with_w)).
  /// Throws std::invalid_argument for invalid options or no descriptors.
  static Vocabulary train(const std::vector<std::vector<Descriptor>>& images, const TrainOptions& options);

  /// Binary file (host byte order: little-endian on x86-64 and ARM64): magic "LTLOBOW1", then uint32 k, L and node count, then per
  /// node (breadth-first, children contiguous) uint16 child count, float32 weight and the 32-byte
  /// descriptor. save() throws FileError when the file cannot be written.
  void save(const std::string& path) const;
  /// Reads and validates a file written by save(): header ranges (k in [2, 255], L in [1, 10]),
  /// size, tree structure (every node below the root is a child of an earlier node, at most k
  /// children, at most L levels, at least one word) and finite non-negative weights. Throws
  /// FileError naming the file, the byte offset and the value at fault.
  static Vocabulary load(const std::string& path);
  /// The same from bytes in memory; `name` stands for the file in messages.
  static Vocabulary fromBytes(const char* data, std::size_t size, const std::string& name);
  /// Human-readable dump: header line, then one line per node
  /// "node_id parent_id depth word_id(-1 inner) weight descriptor_hex".
  void saveText(const std::string& path) const;

  /// Descends the tree for each descriptor; fills the L1-normalised TF-IDF BoW vector and,
  /// if `features` is given, the direct index at tree depth `feature_depth` (1 = root's children;
  /// clamped to [1, depth()]). Feature indices are positions in `descriptors`.
  void transform(const std::vector<Descriptor>& descriptors, BowVector* bow_vector,
                 FeatureVector* features = nullptr, int feature_depth = 2) const;
  /// Word (leaf) a single descriptor falls into; requires numWords() > 0.
  WordId wordOf(const Descriptor& descriptor) const;

  bool empty() const { return nodes_.empty(); }
  int branching() const { return branching_; }
  int depth() const { return depth_; }
  std::size_t numNodes() const { return nodes_.size(); }
  std::size_t numWords() const { return word_nodes_.size(); }
  float wordWeight(WordId word) const { return nodes_[word_nodes_[word]].weight; }

  /// FNV-1a 64 over k, L, the node count and every node's child count, weight bits and centre, in
  /// file order: equal for equal vocabularies (operator==), deterministic across runs and hosts.
  /// Identifies the vocabulary a saved map was built with; O(nodes), no allocation.
  std::uint64_t checksum() const;

  /// Exact equality of structure, centres and weights (round-trip tests).
  bool operator==(const Vocabulary& other) const;

 private:
  struct Node {
    Descriptor centre{};
    float weight = 0.0f;             ///< IDF for leaves, 0 for inner nodes
    std::uint32_t parent = 0;
    std::uint32_t first_child = 0;   ///< children are [first_child, first_child + num_children)
    std::uint16_t num_children = 0;
    std::uint16_t depth = 0;         ///< root 0
    std::int32_t word = -1;          ///< word id for leaves, -1 for inner nodes
  };
  /// Leaf reached by `d`, and the node at `node_depth` on the way (if `node_at_depth`).
  std::uint32_t descend(const Descriptor& d, int node_depth, std::uint32_t* node_at_depth) const;
  /// Fills parent/first_child/depth/word from the child counts in breadth-first order.
  void link();

  int branching_ = 0;
  int depth_ = 0;
  std::vector<Node> nodes_;
  std::vector<std::uint32_t> word_nodes_;  ///< word id -> node id
};

}  // namespace bow
