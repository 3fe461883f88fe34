#include "bow/vocabulary.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <mutex>
#include <random>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace bow {
namespace {

constexpr char kMagic[8] = {'L', 'T', 'L', 'O', 'B', 'O', 'W', '1'};
constexpr std::size_t kHeaderBytes = sizeof(kMagic) + 3 * 4;  // magic, k, L, node count
constexpr std::size_t kNodeBytes = 2 + 4 + 32;                // child count, weight, descriptor

/// Bytes as text for messages: printable ASCII kept, others as \xNN.
std::string printable(const char* data, std::size_t size) {
  std::string text;
  for (std::size_t i = 0; i < size; ++i) {
    const unsigned char c = static_cast<unsigned char>(data[i]);
    if (c >= 0x20 && c < 0x7f) {
      text.push_back(static_cast<char>(c));
    } else {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\x%02x", c);
      text += escaped;
    }
  }
  return text;
}

std::string floatText(float value) {
  std::ostringstream os;
  os << value;
  return os.str();
}

/// Tree under construction; flattened breadth-first once complete.
struct BuildNode {
  Descriptor centre{};
  std::vector<std::unique_ptr<BuildNode>> children;
};

/// Uniform double in [0, 1) from a 64-bit generator (portable, unlike std distributions).
double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

/// Bitwise majority of the descriptors `indices` (k-medians centre under Hamming distance).
Descriptor majority(const std::vector<Descriptor>& data, const std::vector<std::uint32_t>& indices) {
  std::array<std::uint32_t, 256> counts{};
  for (std::uint32_t i : indices) {
    for (int w = 0; w < 4; ++w) {
      std::uint64_t bits = data[i][w];
      while (bits) {
        counts[w * 64 + __builtin_ctzll(bits)]++;
        bits &= bits - 1;
      }
    }
  }
  Descriptor centre{};
  const std::size_t n = indices.size();
  for (int b = 0; b < 256; ++b) {
    if (2 * static_cast<std::size_t>(counts[b]) > n) centre[b / 64] |= std::uint64_t{1} << (b % 64);
  }
  return centre;
}

/// k-means++ seeding with squared Hamming distance as the sampling weight.
std::vector<Descriptor> seedCentres(const std::vector<Descriptor>& data,
                                    const std::vector<std::uint32_t>& indices, int k, std::mt19937_64& rng) {
  std::vector<Descriptor> centres;
  centres.push_back(data[indices[rng() % indices.size()]]);
  std::vector<double> min_dist_sq(indices.size());
  for (std::size_t i = 0; i < indices.size(); ++i) {
    const double d = hammingDistance(data[indices[i]], centres[0]);
    min_dist_sq[i] = d * d;
  }
  while (static_cast<int>(centres.size()) < k) {
    double total = 0.0;
    for (double v : min_dist_sq) total += v;
    if (total <= 0.0) break;  // every descriptor equals a centre already
    const double target = uniform01(rng) * total;
    double cumulative = 0.0;
    std::size_t chosen = indices.size() - 1;
    for (std::size_t i = 0; i < indices.size(); ++i) {
      cumulative += min_dist_sq[i];
      if (cumulative > target) {
        chosen = i;
        break;
      }
    }
    centres.push_back(data[indices[chosen]]);
    for (std::size_t i = 0; i < indices.size(); ++i) {
      const double d = hammingDistance(data[indices[i]], centres.back());
      min_dist_sq[i] = std::min(min_dist_sq[i], d * d);
    }
  }
  return centres;
}

/// Splits `indices` into at most k clusters; returns the non-empty clusters with their centres.
/// The returned assignment is nearest-centre for the returned centres (ties: lower centre), so
/// greedy descent at transform time reproduces it.
void kMedians(const std::vector<Descriptor>& data, const std::vector<std::uint32_t>& indices, int k,
              int max_iterations, std::mt19937_64& rng, std::vector<Descriptor>* centres_out,
              std::vector<std::vector<std::uint32_t>>* clusters_out) {
  std::vector<Descriptor> centres = seedCentres(data, indices, k, rng);
  const int num_centres = static_cast<int>(centres.size());
  std::vector<int> assignment(indices.size(), -1);
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    bool changed = false;
    for (std::size_t i = 0; i < indices.size(); ++i) {
      int best = 0;
      int best_dist = 257;
      for (int c = 0; c < num_centres; ++c) {
        const int d = hammingDistance(data[indices[i]], centres[c]);
        if (d < best_dist) {
          best_dist = d;
          best = c;
        }
      }
      if (assignment[i] != best) {
        assignment[i] = best;
        changed = true;
      }
    }
    if (!changed || iteration + 1 == max_iterations) break;
    std::vector<std::vector<std::uint32_t>> members(num_centres);
    for (std::size_t i = 0; i < indices.size(); ++i) members[assignment[i]].push_back(indices[i]);
    for (int c = 0; c < num_centres; ++c) {
      if (!members[c].empty()) centres[c] = majority(data, members[c]);
    }
  }
  std::vector<std::vector<std::uint32_t>> members(num_centres);
  for (std::size_t i = 0; i < indices.size(); ++i) members[assignment[i]].push_back(indices[i]);
  centres_out->clear();
  clusters_out->clear();
  for (int c = 0; c < num_centres; ++c) {
    if (members[c].empty()) continue;
    centres_out->push_back(centres[c]);
    clusters_out->push_back(std::move(members[c]));
  }
}

void buildSubtree(const std::vector<Descriptor>& data, std::vector<std::uint32_t> indices, int levels_left,
                  const TrainOptions& options, std::uint64_t seed, BuildNode* node) {
  if (levels_left == 0 || indices.size() <= 1) return;
  if (static_cast<int>(indices.size()) <= options.branching) {
    // Few descriptors left: each distinct one becomes a leaf.
    std::vector<Descriptor> distinct;
    for (std::uint32_t i : indices) {
      if (std::find(distinct.begin(), distinct.end(), data[i]) == distinct.end()) distinct.push_back(data[i]);
    }
    if (distinct.size() <= 1) return;
    for (const Descriptor& d : distinct) {
      node->children.push_back(std::make_unique<BuildNode>());
      node->children.back()->centre = d;
    }
    return;
  }
  std::mt19937_64 rng(seed);
  std::vector<Descriptor> centres;
  std::vector<std::vector<std::uint32_t>> clusters;
  kMedians(data, indices, options.branching, options.max_iterations, rng, &centres, &clusters);
  indices.clear();
  indices.shrink_to_fit();
  if (clusters.size() <= 1) return;
  for (std::size_t c = 0; c < clusters.size(); ++c) {
    node->children.push_back(std::make_unique<BuildNode>());
    node->children.back()->centre = centres[c];
    buildSubtree(data, std::move(clusters[c]), levels_left - 1, options,
                 seed * 6364136223846793005ULL + 1442695040888963407ULL + c, node->children.back().get());
  }
}

void writeBytes(std::vector<char>* out, const void* data, std::size_t size) {
  const char* p = static_cast<const char*>(data);
  out->insert(out->end(), p, p + size);
}

}  // namespace

Vocabulary Vocabulary::train(const std::vector<std::vector<Descriptor>>& images, const TrainOptions& options) {
  if (options.branching < 2 || options.branching > 255 || options.depth < 1 || options.depth > 10 ||
      options.max_iterations < 1 || options.num_threads < 1) {
    throw std::invalid_argument("bow::Vocabulary::train: need branching in [2, 255], depth in [1, 10], "
                                "max_iterations >= 1, num_threads >= 1; got branching " +
                                std::to_string(options.branching) + ", depth " + std::to_string(options.depth));
  }
  std::size_t total = 0;
  for (const auto& image : images) total += image.size();
  if (total == 0) throw std::invalid_argument("bow::Vocabulary::train: no training descriptors");
  std::vector<Descriptor> data;
  if (options.max_cluster_descriptors == 0 || total <= options.max_cluster_descriptors) {
    data.reserve(total);
    for (const auto& image : images) data.insert(data.end(), image.begin(), image.end());
  } else {
    // Reservoir sample: deterministic for a given seed and input order.
    std::mt19937_64 sample_rng(options.seed ^ 0x9E3779B97F4A7C15ULL);
    data.reserve(options.max_cluster_descriptors);
    std::size_t seen = 0;
    for (const auto& image : images) {
      for (const Descriptor& d : image) {
        if (data.size() < options.max_cluster_descriptors) {
          data.push_back(d);
        } else {
          const std::size_t j = sample_rng() % (seen + 1);
          if (j < data.size()) data[j] = d;
        }
        ++seen;
      }
    }
  }
  const auto report = [&](const std::string& message) {
    if (options.progress) options.progress(message);
  };
  report("clustering " + std::to_string(data.size()) + " descriptors from " + std::to_string(images.size()) +
         " images into k = " + std::to_string(options.branching) + ", L = " + std::to_string(options.depth));

  // Root split on the calling thread, then the subtrees under the root in parallel; each subtree
  // has its own seed, so the result does not depend on the thread count.
  BuildNode root;
  std::vector<std::uint32_t> all(data.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<std::uint32_t>(i);
  std::vector<std::vector<std::uint32_t>> clusters;
  if (static_cast<int>(all.size()) <= options.branching) {
    buildSubtree(data, all, options.depth, options, options.seed, &root);
  } else {
    std::mt19937_64 rng(options.seed);
    std::vector<Descriptor> centres;
    kMedians(data, all, options.branching, options.max_iterations, rng, &centres, &clusters);
    for (const Descriptor& c : centres) {
      root.children.push_back(std::make_unique<BuildNode>());
      root.children.back()->centre = c;
    }
  }
  all.clear();
  all.shrink_to_fit();
  std::atomic<std::size_t> next_cluster{0};
  std::atomic<std::size_t> done{0};
  std::mutex report_mutex;
  const auto worker = [&]() {
    for (std::size_t c = next_cluster++; c < clusters.size(); c = next_cluster++) {
      buildSubtree(data, std::move(clusters[c]), options.depth - 1, options,
                   options.seed * 2862933555777941757ULL + 3037000493ULL + c, root.children[c].get());
      std::lock_guard<std::mutex> lock(report_mutex);
      report("subtree " + std::to_string(++done) + " / " + std::to_string(clusters.size()) + " done");
    }
  };
  std::vector<std::thread> threads;
  for (int t = 1; t < options.num_threads; ++t) threads.emplace_back(worker);
  worker();
  for (std::thread& t : threads) t.join();

  // Flatten breadth-first so that every node's children are contiguous.
  Vocabulary vocabulary;
  vocabulary.branching_ = options.branching;
  vocabulary.depth_ = options.depth;
  std::vector<const BuildNode*> queue{&root};
  for (std::size_t head = 0; head < queue.size(); ++head) {
    Node node;
    node.centre = queue[head]->centre;
    node.num_children = static_cast<std::uint16_t>(queue[head]->children.size());
    vocabulary.nodes_.push_back(node);
    for (const auto& child : queue[head]->children) queue.push_back(child.get());
  }
  vocabulary.link();

  // IDF from the training images: idf(w) = ln(N / n_w), n_w = images in which word w occurs.
  std::vector<std::uint32_t> images_with_word(vocabulary.numWords(), 0);
  std::vector<std::uint32_t> last_image(vocabulary.numWords(), UINT32_MAX);
  for (std::size_t image = 0; image < images.size(); ++image) {
    for (const Descriptor& d : images[image]) {
      const WordId w = vocabulary.wordOf(d);
      if (last_image[w] != image) {
        last_image[w] = static_cast<std::uint32_t>(image);
        images_with_word[w]++;
      }
    }
  }
  const double num_images = static_cast<double>(images.size());
  for (std::size_t w = 0; w < vocabulary.numWords(); ++w) {
    // A word no training image reaches gets the weight of a word seen once.
    const double n = std::max<double>(1.0, images_with_word[w]);
    vocabulary.nodes_[vocabulary.word_nodes_[w]].weight = static_cast<float>(std::log(num_images / n));
  }
  report("vocabulary: " + std::to_string(vocabulary.numNodes()) + " nodes, " +
         std::to_string(vocabulary.numWords()) + " words");
  return vocabulary;
}

void Vocabulary::link() {
  word_nodes_.clear();
  std::uint32_t next = 1;
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    Node& node = nodes_[i];
    node.first_child = next;
    if (next + node.num_children > nodes_.size()) {
      throw std::runtime_error("bow::Vocabulary: inconsistent child counts at node " + std::to_string(i));
    }
    for (std::uint32_t c = next; c < next + node.num_children; ++c) {
      nodes_[c].parent = static_cast<std::uint32_t>(i);
      nodes_[c].depth = static_cast<std::uint16_t>(node.depth + 1);
    }
    next += node.num_children;
    if (node.num_children == 0 && i != 0) {
      node.word = static_cast<std::int32_t>(word_nodes_.size());
      word_nodes_.push_back(static_cast<std::uint32_t>(i));
    } else {
      node.word = -1;
    }
  }
  if (next != nodes_.size()) {
    throw std::runtime_error("bow::Vocabulary: child counts cover " + std::to_string(next) + " of " +
                             std::to_string(nodes_.size()) + " nodes");
  }
}

std::uint32_t Vocabulary::descend(const Descriptor& d, int node_depth, std::uint32_t* node_at_depth) const {
  std::uint32_t id = 0;
  if (node_at_depth) *node_at_depth = 0;
  while (nodes_[id].num_children > 0) {
    const Node& node = nodes_[id];
    std::uint32_t best = node.first_child;
    int best_dist = 257;
    for (std::uint32_t c = node.first_child; c < node.first_child + node.num_children; ++c) {
      const int dist = hammingDistance(d, nodes_[c].centre);
      if (dist < best_dist) {
        best_dist = dist;
        best = c;
      }
    }
    id = best;
    if (node_at_depth && nodes_[id].depth <= node_depth) *node_at_depth = id;
  }
  return id;
}

WordId Vocabulary::wordOf(const Descriptor& descriptor) const {
  return static_cast<WordId>(nodes_[descend(descriptor, 0, nullptr)].word);
}

void Vocabulary::transform(const std::vector<Descriptor>& descriptors, BowVector* bow_vector,
                           FeatureVector* features, int feature_depth) const {
  bow_vector->entries.clear();
  if (features) features->clear();
  if (word_nodes_.empty() || descriptors.empty()) return;
  feature_depth = std::clamp(feature_depth, 1, depth_);
  std::vector<WordId> words(descriptors.size());
  for (std::size_t i = 0; i < descriptors.size(); ++i) {
    std::uint32_t node_at_depth = 0;
    const std::uint32_t leaf = descend(descriptors[i], feature_depth, features ? &node_at_depth : nullptr);
    words[i] = static_cast<WordId>(nodes_[leaf].word);
    if (features) (*features)[node_at_depth].push_back(static_cast<std::uint32_t>(i));
  }
  std::sort(words.begin(), words.end());
  double total = 0.0;
  for (std::size_t i = 0; i < words.size();) {
    std::size_t j = i;
    while (j < words.size() && words[j] == words[i]) ++j;
    const float value = static_cast<float>(j - i) * wordWeight(words[i]);  // tf * idf (tf unnormalised)
    if (value > 0.0f) {
      bow_vector->entries.emplace_back(words[i], value);
      total += value;
    }
    i = j;
  }
  if (total > 0.0) {
    for (auto& entry : bow_vector->entries) entry.second = static_cast<float>(entry.second / total);
  }
}

void Vocabulary::save(const std::string& path) const {
  std::vector<char> buffer;
  buffer.reserve(kHeaderBytes + nodes_.size() * kNodeBytes);
  writeBytes(&buffer, kMagic, sizeof(kMagic));
  const std::uint32_t header[3] = {static_cast<std::uint32_t>(branching_), static_cast<std::uint32_t>(depth_),
                                   static_cast<std::uint32_t>(nodes_.size())};
  writeBytes(&buffer, header, sizeof(header));
  for (const Node& node : nodes_) {
    writeBytes(&buffer, &node.num_children, 2);
    writeBytes(&buffer, &node.weight, 4);
    writeBytes(&buffer, node.centre.data(), 32);
  }
  std::ofstream out(path, std::ios::binary);
  if (!out) throw FileError(path, -1, "cannot open the vocabulary file for writing");
  out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  if (!out) throw FileError(path, -1, "write failed");
}

Vocabulary Vocabulary::load(const std::string& path) {
  std::error_code error;
  if (!std::filesystem::exists(path, error)) throw FileError(path, -1, "vocabulary file does not exist");
  if (!std::filesystem::is_regular_file(path, error)) throw FileError(path, -1, "not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError(path, -1, "cannot open the vocabulary file");
  const std::vector<char> buffer((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw FileError(path, -1, "read failed");
  return fromBytes(buffer.data(), buffer.size(), path);
}

Vocabulary Vocabulary::fromBytes(const char* data, std::size_t size, const std::string& name) {
  if (size < kHeaderBytes) {
    throw FileError(name, 0, "too short for the LTLOBOW1 header: " + std::to_string(size) + " bytes",
                    "need " + std::to_string(kHeaderBytes));
  }
  if (std::memcmp(data, kMagic, sizeof(kMagic)) != 0) {
    throw FileError(name, 0, "not an LTLOBOW1 vocabulary file", "magic '" + printable(data, sizeof(kMagic)) + "'");
  }
  std::uint32_t header[3];
  std::memcpy(header, data + sizeof(kMagic), sizeof(header));
  if (header[0] < 2 || header[0] > 255) {
    throw FileError(name, 8, "branching factor k outside [2, 255]", std::to_string(header[0]));
  }
  if (header[1] < 1 || header[1] > 10) {
    throw FileError(name, 12, "depth L outside [1, 10]", std::to_string(header[1]));
  }
  const std::size_t num_nodes = header[2];
  const std::size_t body_bytes = size - kHeaderBytes;
  if (num_nodes < 2 || body_bytes != num_nodes * kNodeBytes) {
    throw FileError(name, 16,
                    "node count does not match the file size " + std::to_string(size) + " bytes (" +
                        std::to_string(kHeaderBytes) + " + nodes * " + std::to_string(kNodeBytes) +
                        ", at least a root and one word)",
                    std::to_string(num_nodes));
  }
  Vocabulary vocabulary;
  vocabulary.branching_ = static_cast<int>(header[0]);
  vocabulary.depth_ = static_cast<int>(header[1]);
  vocabulary.nodes_.resize(num_nodes);
  // Checks the breadth-first layout while reading: node i > 0 must already be claimed as a child
  // of an earlier node (i < next_child), so the children ranges tile [1, num_nodes) in order and
  // the tree has no cycles, no orphans and no node deeper than L.
  std::size_t next_child = 1;
  std::vector<std::uint32_t> node_depth(num_nodes, 0);
  for (std::size_t i = 0; i < num_nodes; ++i) {
    const std::size_t offset = kHeaderBytes + i * kNodeBytes;
    const char* p = data + offset;
    Node& node = vocabulary.nodes_[i];
    std::memcpy(&node.num_children, p, 2);
    std::memcpy(&node.weight, p + 2, 4);
    std::memcpy(node.centre.data(), p + 6, 32);
    const std::string node_text = "node " + std::to_string(i);
    if (i > 0 && i >= next_child) {
      throw FileError(name, static_cast<long long>(offset),
                      node_text + " is no node's child (earlier child counts cover nodes 1.." +
                          std::to_string(next_child - 1) + ")");
    }
    if (node.num_children > vocabulary.branching_) {
      throw FileError(name, static_cast<long long>(offset),
                      node_text + ": more children than k = " + std::to_string(vocabulary.branching_),
                      std::to_string(node.num_children));
    }
    if (!std::isfinite(node.weight) || node.weight < 0.0f) {
      throw FileError(name, static_cast<long long>(offset + 2),
                      node_text + ": weight is not a finite non-negative number", floatText(node.weight));
    }
    if (next_child + node.num_children > num_nodes) {
      throw FileError(name, static_cast<long long>(offset),
                      node_text + ": children beyond the " + std::to_string(num_nodes) + " nodes",
                      std::to_string(node.num_children));
    }
    if (node.num_children > 0 && node_depth[i] + 1 > static_cast<std::uint32_t>(vocabulary.depth_)) {
      throw FileError(name, static_cast<long long>(offset),
                      node_text + " at depth " + std::to_string(node_depth[i]) + " has children, but L = " +
                          std::to_string(vocabulary.depth_),
                      std::to_string(node.num_children));
    }
    for (std::size_t c = next_child; c < next_child + node.num_children; ++c) node_depth[c] = node_depth[i] + 1;
    next_child += node.num_children;
  }
  vocabulary.link();  // cannot fail now: the last node was claimed, so the ranges end at num_nodes
  return vocabulary;
}

void Vocabulary::saveText(const std::string& path) const {
  std::ofstream out(path);
  if (!out) throw FileError(path, -1, "cannot open for writing");
  out << "# LTLO bow vocabulary k " << branching_ << " L " << depth_ << " nodes " << nodes_.size() << " words "
      << word_nodes_.size() << "\n# node_id parent_id depth word_id weight descriptor_hex(word0..word3)\n";
  char hex[80];
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const Node& n = nodes_[i];
    std::snprintf(hex, sizeof(hex), "%016llx%016llx%016llx%016llx", static_cast<unsigned long long>(n.centre[0]),
                  static_cast<unsigned long long>(n.centre[1]), static_cast<unsigned long long>(n.centre[2]),
                  static_cast<unsigned long long>(n.centre[3]));
    out << i << ' ' << (i == 0 ? -1 : static_cast<long>(n.parent)) << ' ' << n.depth << ' ' << n.word << ' '
        << n.weight << ' ' << hex << '\n';
  }
  if (!out) throw FileError(path, -1, "write failed");
}

bool Vocabulary::operator==(const Vocabulary& other) const {
  if (branching_ != other.branching_ || depth_ != other.depth_ || nodes_.size() != other.nodes_.size()) return false;
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const Node& a = nodes_[i];
    const Node& b = other.nodes_[i];
    if (a.centre != b.centre || a.weight != b.weight || a.num_children != b.num_children) return false;
  }
  return true;
}

std::uint64_t Vocabulary::checksum() const {
  std::uint64_t hash = 14695981039346656037ULL;  // FNV-1a 64 offset basis
  auto mix = [&hash](std::uint64_t value, int bytes) {
    for (int k = 0; k < bytes; ++k) {  // little-endian byte order, whatever the host
      hash ^= (value >> (8 * k)) & 0xFFu;
      hash *= 1099511628211ULL;
    }
  };
  mix(static_cast<std::uint32_t>(branching_), 4);
  mix(static_cast<std::uint32_t>(depth_), 4);
  mix(nodes_.size(), 8);
  for (const Node& node : nodes_) {
    mix(node.num_children, 2);
    std::uint32_t weight_bits = 0;
    std::memcpy(&weight_bits, &node.weight, sizeof(weight_bits));
    mix(weight_bits, 4);
    for (const std::uint64_t word : node.centre) mix(word, 8);
  }
  return hash;
}

}  // namespace bow
