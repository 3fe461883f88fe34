#include "ltlo/segmentation/depth_clustering.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "ltlo/core/assert.h"

namespace ltlo::segmentation {

namespace {

bool validDepth(float depth_m) { return depth_m > 0.0f && std::isfinite(depth_m); }

// The subsampled depth: one sample per step x step block (the first valid pixel of the block in
// raster order, never an average, so no sample floats between two surfaces), back-projected at
// its own full-resolution pixel.
struct WorkingImage {
  int step = 1;
  int width = 0;
  int height = 0;
  std::vector<float> x, y, z;  // camera frame, m; z = 0 where the block has no depth
  std::vector<int> valid;      // indices of samples with depth
};

void subsample(const cv::Mat& depth_m, const PinholeCamera& camera,
               const DepthClusteringOptions& options, WorkingImage* image_out) {
  WorkingImage& image = *image_out;
  image.step = std::max(
      1, std::min(depth_m.cols / options.working_width, depth_m.rows / options.working_height));
  image.width = depth_m.cols / image.step;
  image.height = depth_m.rows / image.step;
  const size_t size = static_cast<size_t>(image.width) * image.height;
  image.x.assign(size, 0.0f);
  image.y.assign(size, 0.0f);
  image.z.assign(size, 0.0f);
  image.valid.clear();
  image.valid.reserve(size);
  const float inv_fx = static_cast<float>(1.0 / camera.fx());
  const float inv_fy = static_cast<float>(1.0 / camera.fy());
  const float cx = static_cast<float>(camera.cx());
  const float cy = static_cast<float>(camera.cy());
  const int step = image.step;
  for (int wy = 0; wy < image.height; ++wy) {
    for (int wx = 0; wx < image.width; ++wx) {
      const int i = wy * image.width + wx;
      for (int dv = 0; dv < step && image.z[i] == 0.0f; ++dv) {
        const int v = wy * step + dv;
        const float* row = depth_m.ptr<float>(v);
        for (int du = 0; du < step; ++du) {
          const int u = wx * step + du;
          const float z = row[u];
          if (!validDepth(z)) continue;
          image.x[i] = (static_cast<float>(u) - cx) * inv_fx * z;
          image.y[i] = (static_cast<float>(v) - cy) * inv_fy * z;
          image.z[i] = z;
          break;
        }
      }
      if (image.z[i] > 0.0f) image.valid.push_back(i);
    }
  }
}

// Forward 3-D tangent between neighbouring samples; ok = false where they are not on one surface.
struct Tangent {
  float x = 0.0f, y = 0.0f, z = 0.0f;
  bool ok = false;
};

}  // namespace

// Per-sample buffers kept between frames: allocating them afresh costs more than the clustering
// (page faults on every call, glibc serves blocks this large with mmap).
struct detail::ClusteringBuffers {
  WorkingImage image;
  std::vector<char> used;
  std::vector<Tangent> right, down;
  std::vector<uint8_t> smooth_right, smooth_down;
  std::vector<int> parent, piece, piece_size, group_parent, group_index, group_of;
  std::vector<int> lloyd_samples, sample_label, working_label;
  std::vector<uint8_t> uniform;
};

namespace {

// Seeds on a uniform gx x gy grid over the working image (gx * gy >= K, K cells picked evenly);
// a cell centre without depth moves to the nearest (Chebyshev rings) valid sample not yet a seed.
std::vector<int> gridSeeds(const WorkingImage& image, int num_clusters,
                           std::vector<char>* used_buffer) {
  const int w = image.width, h = image.height;
  const int grid_rows = std::max(
      1, static_cast<int>(std::lround(std::sqrt(num_clusters * static_cast<double>(h) / w))));
  const int grid_cols = (num_clusters + grid_rows - 1) / grid_rows;
  const int num_cells = grid_rows * grid_cols;
  std::vector<char>& used = *used_buffer;
  used.assign(image.z.size(), 0);
  std::vector<int> seeds;
  seeds.reserve(num_clusters);
  for (int s = 0; s < num_clusters; ++s) {
    const int cell = static_cast<int>((s + 0.5) * num_cells / num_clusters);
    const int cu = static_cast<int>((cell % grid_cols + 0.5) * w / grid_cols);
    const int cv = static_cast<int>((cell / grid_cols + 0.5) * h / grid_rows);
    int best = -1;
    long best_d2 = std::numeric_limits<long>::max();
    for (int r = 0; best < 0 && r < std::max(w, h); ++r) {
      for (int v = std::max(0, cv - r); v <= std::min(h - 1, cv + r); ++v) {
        const bool edge_row = (v == cv - r || v == cv + r);
        const int u_step = edge_row ? 1 : 2 * r;
        for (int u = cu - r; u <= cu + r; u += std::max(1, u_step)) {
          if (u < 0 || u >= w) continue;
          const int i = v * w + u;
          if (image.z[i] == 0.0f || used[i]) continue;
          const long d2 =
              static_cast<long>(u - cu) * (u - cu) + static_cast<long>(v - cv) * (v - cv);
          if (d2 < best_d2) {
            best_d2 = d2;
            best = i;
          }
        }
      }
    }
    LTLO_ASSERT(best >= 0, "no free valid sample for seed " << s);
    used[best] = 1;
    seeds.push_back(best);
  }
  return seeds;
}

// Centres as structure-of-arrays, with |c|^2, so that the nearest centre of p minimises
// |c|^2 - 2 p.c (the |p|^2 term is common to all centres).
struct Centres {
  std::vector<float> x, y, z, norm2;
  int size() const { return static_cast<int>(x.size()); }
  void set(int k, float cx, float cy, float cz) {
    x[k] = cx;
    y[k] = cy;
    z[k] = cz;
    norm2[k] = cx * cx + cy * cy + cz * cz;
  }
  explicit Centres(int k) : x(k), y(k), z(k), norm2(k) {}
};

constexpr int kMaxClusters = 256;  // Seg.Clusters range

// Returns the nearest centre of p; *score = |c|^2 - 2 p.c for it.
inline int nearestCentre(const Centres& c, float px, float py, float pz, float* score) {
  float d[kMaxClusters];
  const int k_count = c.size();
  const float* cx = c.x.data();
  const float* cy = c.y.data();
  const float* cz = c.z.data();
  const float* cn = c.norm2.data();
  const float px2 = 2.0f * px, py2 = 2.0f * py, pz2 = 2.0f * pz;
  for (int k = 0; k < k_count; ++k) d[k] = cn[k] - (px2 * cx[k] + py2 * cy[k] + pz2 * cz[k]);
  int best = 0;
  float best_d = std::numeric_limits<float>::max();
  for (int k = 0; k < k_count; ++k) {
    if (d[k] < best_d) {
      best_d = d[k];
      best = k;
    }
  }
  *score = best_d;
  return best;
}

int findRoot(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

// K-means on 3-D points ignores surface breaks: a thin far strip between two near objects has no
// centre of its own and joins a near cluster, and a box standing on the floor shares clusters with
// it. This pass makes every cluster one piece of smooth surface while keeping K. Two 4-neighbour
// samples are on one smooth surface when their depths differ by less than the gap threshold and
// the surface does not fold between them (normals from each side's own samples differ by less
// than max_crease_angle).
//  1. each cluster keeps its largest smooth-connected piece (its main piece);
//  2. the other pieces, joined where they touch smoothly, form orphan groups; a group that touches
//     main pieces smoothly joins the cluster it touches most;
//  3. an isolated group (an island behind depth steps or creases) of at least min_island_share of
//     the samples takes the label freed by merging the two smoothly adjacent clusters of smallest
//     joint size, largest islands first. Smaller islands keep their labels.
void splitAtSurfaceBreaks(const WorkingImage& image, const DepthClusteringOptions& options, int K,
                          std::vector<int>* working_label, detail::ClusteringBuffers* buffers) {
  std::vector<int>& label = *working_label;
  const int w = image.width, h = image.height;
  const int n = w * h;
  const float cos_crease = static_cast<float>(std::cos(options.max_crease_angle_rad));
  const float gap_at_zero_m = static_cast<float>(options.gap_at_zero_m);
  const float gap_growth_per_m = static_cast<float>(options.gap_growth_per_m);
  const float max_gap_m = static_cast<float>(options.max_gap_m);
  auto depthSmooth = [&](int i, int j) {  // gapThreshold() in float
    const float zi = image.z[i], zj = image.z[j];
    const float z_mean = 0.5f * (zi + zj);
    return zi > 0.0f && zj > 0.0f &&
           std::abs(zi - zj) <
               std::min(max_gap_m, gap_at_zero_m + gap_growth_per_m * z_mean * z_mean);
  };
  // Forward tangents P(i + 1) - P(i) (right) and P(i + w) - P(i) (down) where both samples are on
  // one surface in depth (ok = false otherwise); each link's side normals are built from these.
  std::vector<Tangent>& right = buffers->right;
  std::vector<Tangent>& down = buffers->down;
  right.assign(n, Tangent{});
  down.assign(n, Tangent{});
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int i = y * w + x;
      if (x + 1 < w && depthSmooth(i, i + 1)) {
        right[i] = {image.x[i + 1] - image.x[i], image.y[i + 1] - image.y[i],
                    image.z[i + 1] - image.z[i], true};
      }
      if (y + 1 < h && depthSmooth(i, i + w)) {
        down[i] = {image.x[i + w] - image.x[i], image.y[i + w] - image.y[i],
                   image.z[i + w] - image.z[i], true};
      }
    }
  }
  // Tangent across a link at one sample: the sum of the forward tangents on both sides of it
  // (a central difference), or the one available; false when neither is.
  auto sumTangents = [](const Tangent* low, const Tangent& high, Tangent* t) {
    const bool has_low = low != nullptr && low->ok;
    if (!has_low && !high.ok) return false;
    t->x = (has_low ? low->x : 0.0f) + (high.ok ? high.x : 0.0f);
    t->y = (has_low ? low->y : 0.0f) + (high.ok ? high.y : 0.0f);
    t->z = (has_low ? low->z : 0.0f) + (high.ok ? high.z : 0.0f);
    return true;
  };
  // Link i -> j: each side's surface normal comes from samples on its own side of the link only
  // (the tangent leading into / out of the link and the tangent across it at that sample), so a
  // crease right at the link shows.
  auto creaseFree = [&](const Tangent& t_in, const Tangent& t_out, const Tangent& s_i,
                        const Tangent& s_j) {
    const float n_i[3] = {t_in.y * s_i.z - t_in.z * s_i.y, t_in.z * s_i.x - t_in.x * s_i.z,
                          t_in.x * s_i.y - t_in.y * s_i.x};
    const float n_j[3] = {t_out.y * s_j.z - t_out.z * s_j.y, t_out.z * s_j.x - t_out.x * s_j.z,
                          t_out.x * s_j.y - t_out.y * s_j.x};
    const float dot = n_i[0] * n_j[0] + n_i[1] * n_j[1] + n_i[2] * n_j[2];
    const float norms2 = (n_i[0] * n_i[0] + n_i[1] * n_i[1] + n_i[2] * n_i[2]) *
                         (n_j[0] * n_j[0] + n_j[1] * n_j[1] + n_j[2] * n_j[2]);
    return norms2 <= 0.0f || (dot >= 0.0f && dot * dot >= cos_crease * cos_crease * norms2);
  };
  std::vector<uint8_t>& smooth_right = buffers->smooth_right;
  std::vector<uint8_t>& smooth_down = buffers->smooth_down;
  smooth_right.assign(n, 0);
  smooth_down.assign(n, 0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int i = y * w + x;
      Tangent s_i, s_j;
      if (right[i].ok) {  // link i -> i + 1
        const int j = i + 1;
        smooth_right[i] = x == 0 || x + 2 >= w || !right[i - 1].ok || !right[j].ok ||
                          !sumTangents(y > 0 ? &down[i - w] : nullptr, down[i], &s_i) ||
                          !sumTangents(y > 0 ? &down[j - w] : nullptr, down[j], &s_j) ||
                          creaseFree(right[i - 1], right[j], s_i, s_j);
      }
      if (down[i].ok) {  // link i -> i + w
        const int j = i + w;
        smooth_down[i] = y == 0 || y + 2 >= h || !down[i - w].ok || !down[j].ok ||
                         !sumTangents(x > 0 ? &right[i - 1] : nullptr, right[i], &s_i) ||
                         !sumTangents(x > 0 ? &right[j - 1] : nullptr, right[j], &s_j) ||
                         creaseFree(down[i - w], down[j], s_i, s_j);
      }
    }
  }
  auto forEachSmoothLink = [&](auto&& visit) {
    for (int i = 0; i < n; ++i) {
      if (smooth_right[i]) visit(i, i + 1);
      if (smooth_down[i]) visit(i, i + w);
    }
  };
  auto unite = [](std::vector<int>& parent, int i, int j) {
    const int ri = findRoot(parent, i), rj = findRoot(parent, j);
    if (ri != rj) parent[std::max(ri, rj)] = std::min(ri, rj);
  };

  // Pieces: same label, smoothly connected.
  std::vector<int>& parent = buffers->parent;
  parent.resize(n);
  for (int i = 0; i < n; ++i) parent[i] = i;
  forEachSmoothLink([&](int i, int j) {
    if (label[i] == label[j]) unite(parent, i, j);
  });
  std::vector<int>& piece = buffers->piece;
  std::vector<int>& piece_size = buffers->piece_size;
  piece.assign(n, -1);
  piece_size.assign(n, 0);
  for (const int i : image.valid) {
    piece[i] = findRoot(parent, i);
    ++piece_size[piece[i]];
  }
  std::vector<int> main_piece(K, -1);
  for (const int i : image.valid) {
    const int k = label[i];
    if (piece[i] == i && (main_piece[k] < 0 || piece_size[i] > piece_size[main_piece[k]])) {
      main_piece[k] = i;
    }
  }
  auto isMain = [&](int i) { return piece[i] == main_piece[label[i]]; };

  // Orphan groups: non-main pieces joined across smooth links.
  std::vector<int>& group_parent = buffers->group_parent;
  group_parent.resize(n);
  for (int i = 0; i < n; ++i) group_parent[i] = i;
  bool any_orphan = false;
  for (const int i : image.valid) any_orphan = any_orphan || !isMain(i);
  if (!any_orphan) return;
  forEachSmoothLink([&](int i, int j) {
    if (!isMain(i) && !isMain(j)) unite(group_parent, piece[i], piece[j]);
  });
  std::vector<int>& group_index = buffers->group_index;
  std::vector<int>& group_of = buffers->group_of;
  group_index.assign(n, -1);
  group_of.assign(n, -1);
  std::vector<int> group_roots;
  for (const int i : image.valid) {
    if (isMain(i)) continue;
    const int g = findRoot(group_parent, piece[i]);
    if (group_index[g] < 0) {
      group_index[g] = static_cast<int>(group_roots.size());
      group_roots.push_back(g);
    }
    group_of[i] = group_index[g];
  }
  const int num_groups = static_cast<int>(group_roots.size());
  std::vector<int> group_size(num_groups, 0);
  for (const int i : image.valid) {
    if (group_of[i] >= 0) ++group_size[group_of[i]];
  }
  std::vector<int> votes(static_cast<size_t>(num_groups) * K, 0);
  std::vector<int> adjacency(static_cast<size_t>(K) * K, 0);
  std::vector<int> cluster_size(K, 0);
  for (const int i : image.valid) {
    if (isMain(i)) ++cluster_size[label[i]];
  }
  forEachSmoothLink([&](int i, int j) {
    const bool main_i = isMain(i), main_j = isMain(j);
    if (main_i && main_j) {
      if (label[i] == label[j]) return;
      ++adjacency[static_cast<size_t>(label[i]) * K + label[j]];
      ++adjacency[static_cast<size_t>(label[j]) * K + label[i]];
    } else if (main_j) {
      ++votes[static_cast<size_t>(group_of[i]) * K + label[j]];
    } else if (main_i) {
      ++votes[static_cast<size_t>(group_of[j]) * K + label[i]];
    }
  });
  // New label of each group; -1 = island keeping its labels.
  std::vector<int> new_label(num_groups, -1);
  std::vector<int> islands;
  for (int g = 0; g < num_groups; ++g) {
    const int* v = &votes[static_cast<size_t>(g) * K];
    const int best = static_cast<int>(std::max_element(v, v + K) - v);
    if (v[best] > 0) {
      new_label[g] = best;
      cluster_size[best] += group_size[g];
    } else {
      islands.push_back(g);
    }
  }
  std::stable_sort(islands.begin(), islands.end(),
                   [&](int a, int b) { return group_size[a] > group_size[b]; });
  const int min_island_samples =
      std::max(4, static_cast<int>(options.min_island_share * image.valid.size()));
  std::vector<int> merged_into(K);
  for (int k = 0; k < K; ++k) merged_into[k] = k;
  for (const int g : islands) {
    if (group_size[g] < min_island_samples) break;
    int best_a = -1, best_b = -1;
    long best_cost = std::numeric_limits<long>::max();
    for (int a = 0; a < K; ++a) {
      for (int b = a + 1; b < K; ++b) {
        if (adjacency[static_cast<size_t>(a) * K + b] == 0) continue;
        const long cost = static_cast<long>(cluster_size[a]) + cluster_size[b];
        if (cost < best_cost) {
          best_cost = cost;
          best_a = a;
          best_b = b;
        }
      }
    }
    if (best_a < 0) break;
    // b joins a; the island takes label b.
    for (int c = 0; c < K; ++c) {
      adjacency[static_cast<size_t>(best_a) * K + c] +=
          adjacency[static_cast<size_t>(best_b) * K + c];
      adjacency[static_cast<size_t>(c) * K + best_a] +=
          adjacency[static_cast<size_t>(c) * K + best_b];
      adjacency[static_cast<size_t>(best_b) * K + c] = 0;
      adjacency[static_cast<size_t>(c) * K + best_b] = 0;
    }
    adjacency[static_cast<size_t>(best_a) * K + best_a] = 0;
    for (int k = 0; k < K; ++k) {
      if (merged_into[k] == best_b) merged_into[k] = best_a;
    }
    for (int other = 0; other < num_groups; ++other) {
      if (new_label[other] == best_b) new_label[other] = best_a;
    }
    cluster_size[best_a] += cluster_size[best_b];
    cluster_size[best_b] = group_size[g];
    new_label[g] = best_b;
  }
  for (const int i : image.valid) {
    const int g = group_of[i];
    label[i] = (g >= 0 && new_label[g] >= 0) ? new_label[g] : merged_into[label[i]];
  }
}

}  // namespace

DepthClusteringOptions DepthClusteringOptions::from(const SegmentationOptions& segmentation,
                                                    const DenseOptions& dense) {
  DepthClusteringOptions options;
  options.num_clusters = segmentation.num_clusters;
  options.kmeans_iterations = segmentation.kmeans_iterations;
  options.max_gap_m = segmentation.max_neighbour_gap_m;
  options.working_width = dense.width;
  options.working_height = dense.height;
  return options;
}

double DepthClusteringOptions::gapThreshold(double z_m) const {
  return std::min(max_gap_m, gap_at_zero_m + gap_growth_per_m * z_m * z_m);
}

DepthClustering::~DepthClustering() = default;
DepthClustering::DepthClustering(DepthClustering&&) noexcept = default;
DepthClustering& DepthClustering::operator=(DepthClustering&&) noexcept = default;

DepthClustering::DepthClustering(const DepthClusteringOptions& options)
    : options_(options), buffers_(std::make_unique<detail::ClusteringBuffers>()) {
  LTLO_ASSERT(
      options.num_clusters >= 1 && options.num_clusters <= kMaxClusters,
      "num_clusters = " << options.num_clusters << ", expected [1, " << kMaxClusters << "]");
  LTLO_ASSERT(options.kmeans_iterations >= 1, "kmeans_iterations = " << options.kmeans_iterations);
  LTLO_ASSERT(options.working_width >= 1 && options.working_height >= 1,
              "working size " << options.working_width << "x" << options.working_height);
}

ClusterMap DepthClustering::cluster(const cv::Mat& depth_m, const PinholeCamera& camera) {
  LTLO_ASSERT(depth_m.type() == CV_32F, "depth type " << depth_m.type() << ", expected CV_32F");
  LTLO_ASSERT(depth_m.cols == camera.width() && depth_m.rows == camera.height(),
              "depth " << depth_m.cols << "x" << depth_m.rows << ", camera " << camera.width()
                       << "x" << camera.height());
  detail::ClusteringBuffers& buffers = *buffers_;
  subsample(depth_m, camera, options_, &buffers.image);
  const WorkingImage& image = buffers.image;
  const int num_valid = static_cast<int>(image.valid.size());
  const int K = std::min(options_.num_clusters, num_valid);

  ClusterMap result;
  result.num_clusters = K;
  result.labels = cv::Mat(depth_m.size(), CV_32S, cv::Scalar(K));
  result.pixel_counts.assign(K + 1, 0);
  if (K == 0) {
    result.pixel_counts[0] = static_cast<int>(depth_m.total());
    return result;
  }

  // Lloyd iterations on the valid working samples.
  Centres centres(K);
  {
    const std::vector<int> seeds = gridSeeds(image, K, &buffers.used);
    for (int k = 0; k < K; ++k) {
      const int i = seeds[k];
      centres.set(k, image.x[i], image.y[i], image.z[i]);
    }
  }
  // The Lloyd iterations run on every other sample in both directions (a quarter of them) when
  // that leaves at least 16 per cluster; a final assignment then labels all samples.
  std::vector<int>& lloyd_samples = buffers.lloyd_samples;
  lloyd_samples.clear();
  for (int n = 0; n < num_valid; ++n) {
    const int i = image.valid[n];
    if ((i % image.width) % 2 == 0 && (i / image.width) % 2 == 0) lloyd_samples.push_back(n);
  }
  if (static_cast<int>(lloyd_samples.size()) < 16 * K) {
    lloyd_samples.resize(num_valid);
    for (int n = 0; n < num_valid; ++n) lloyd_samples[n] = n;
  }
  std::vector<int>& sample_label = buffers.sample_label;
  sample_label.assign(num_valid, 0);
  std::vector<double> sum_x(K), sum_y(K), sum_z(K);
  std::vector<int> count(K);
  for (int iteration = 0; iteration < options_.kmeans_iterations; ++iteration) {
    std::fill(sum_x.begin(), sum_x.end(), 0.0);
    std::fill(sum_y.begin(), sum_y.end(), 0.0);
    std::fill(sum_z.begin(), sum_z.end(), 0.0);
    std::fill(count.begin(), count.end(), 0);
    float worst_d2 = -1.0f;
    int worst_sample = 0;
    for (const int n : lloyd_samples) {
      const int i = image.valid[n];
      const float px = image.x[i], py = image.y[i], pz = image.z[i];
      float score;
      const int k = nearestCentre(centres, px, py, pz, &score);
      sum_x[k] += px;
      sum_y[k] += py;
      sum_z[k] += pz;
      ++count[k];
      const float d2 = score + px * px + py * py + pz * pz;
      if (d2 > worst_d2) {
        worst_d2 = d2;
        worst_sample = n;
      }
    }
    const bool last = iteration + 1 == options_.kmeans_iterations;
    bool reseeded = false;
    for (int k = 0; k < K; ++k) {
      if (count[k] > 0) {
        centres.set(k, static_cast<float>(sum_x[k] / count[k]),
                    static_cast<float>(sum_y[k] / count[k]),
                    static_cast<float>(sum_z[k] / count[k]));
      } else if (!last && !reseeded) {
        // An empty cluster restarts at the sample worst served by its centre (keeps K clusters).
        const int i = image.valid[worst_sample];
        centres.set(k, image.x[i], image.y[i], image.z[i]);
        reseeded = true;
      }
    }
  }
  for (int n = 0; n < num_valid; ++n) {
    const int i = image.valid[n];
    float score;
    sample_label[n] = nearestCentre(centres, image.x[i], image.y[i], image.z[i], &score);
  }
  // Working label image, cut at depth steps and creases; centroids are the means of the final
  // clusters.
  std::vector<int>& working_label = buffers.working_label;
  working_label.assign(image.z.size(), K);
  for (int n = 0; n < num_valid; ++n) working_label[image.valid[n]] = sample_label[n];
  splitAtSurfaceBreaks(image, options_, K, &working_label, &buffers);
  {
    std::vector<Vec3> sum(K, Vec3::Zero());
    std::vector<int> members(K, 0);
    for (const int i : image.valid) {
      const int k = working_label[i];
      sum[k] += Vec3(image.x[i], image.y[i], image.z[i]);
      ++members[k];
    }
    for (int k = 0; k < K; ++k) {
      const Vec3 centre = members[k] > 0 ? Vec3(sum[k] / members[k])
                                         : Vec3(centres.x[k], centres.y[k], centres.z[k]);
      result.centroids_c.push_back(centre);
      centres.set(k, static_cast<float>(centre.x()), static_cast<float>(centre.y()),
                  static_cast<float>(centre.z()));
    }
  }

  // Connectivity graph V over 4-neighbour boundary pairs.
  std::vector<int> boundary_pairs(static_cast<size_t>(K) * K, 0);
  auto link = [&](int i, int j) {
    const int a = working_label[i], b = working_label[j];
    if (a == b || a == K || b == K) return;
    const float z_mean = 0.5f * (image.z[i] + image.z[j]);
    if (std::abs(image.z[i] - image.z[j]) < options_.gapThreshold(z_mean)) {
      ++boundary_pairs[static_cast<size_t>(std::min(a, b)) * K + std::max(a, b)];
    }
  };
  for (int wy = 0; wy < image.height; ++wy) {
    for (int wx = 0; wx < image.width; ++wx) {
      const int i = wy * image.width + wx;
      if (wx + 1 < image.width) link(i, i + 1);
      if (wy + 1 < image.height) link(i, i + image.width);
    }
  }
  for (int a = 0; a < K; ++a) {
    for (int b = a + 1; b < K; ++b) {
      const int pairs = boundary_pairs[static_cast<size_t>(a) * K + b];
      if (pairs > 0) result.edges.push_back({a, b, pairs});
    }
  }

  // Full-resolution labels: a pixel with depth takes the label of the 3-D-nearest valid working
  // sample in the 3x3 samples around its own (depth-guided nearest-neighbour upsampling, so labels
  // stay on the right side of depth steps); without any, the nearest centre.
  const int step = image.step;
  // Samples inside a cluster (all 3x3 samples around share its label) label their pixels directly.
  std::vector<uint8_t>& uniform_sample = buffers.uniform;
  uniform_sample.assign(image.z.size(), 0);
  if (step > 1) {
    for (int wy = 0; wy < image.height; ++wy) {
      for (int wx = 0; wx < image.width; ++wx) {
        const int i = wy * image.width + wx;
        const int k = working_label[i];
        bool uniform = k != K;
        const int sy1 = std::min(image.height - 1, wy + 1);
        for (int sy = std::max(0, wy - 1); sy <= sy1 && uniform; ++sy) {
          for (int sx = std::max(0, wx - 1); sx <= std::min(image.width - 1, wx + 1); ++sx) {
            if (working_label[sy * image.width + sx] != k) {
              uniform = false;
              break;
            }
          }
        }
        uniform_sample[i] = uniform;
      }
    }
  }
  const float inv_fx = static_cast<float>(1.0 / camera.fx());
  const float inv_fy = static_cast<float>(1.0 / camera.fy());
  const float cx = static_cast<float>(camera.cx());
  const float cy = static_cast<float>(camera.cy());
  for (int v = 0; v < depth_m.rows; ++v) {
    const float* depth_row = depth_m.ptr<float>(v);
    int* label_row = result.labels.ptr<int>(v);
    const int wy = std::min(v / step, image.height - 1);
    const int wy0 = std::max(0, wy - 1), wy1 = std::min(image.height - 1, wy + 1);
    for (int u = 0; u < depth_m.cols; ++u) {
      const float z = depth_row[u];
      if (!validDepth(z)) {
        ++result.pixel_counts[K];
        continue;
      }
      const int wx = std::min(u / step, image.width - 1);
      int label = working_label[wy * image.width + wx];
      const bool uniform = step == 1 || buffers.uniform[wy * image.width + wx];
      if (!uniform) {
        const float px = (static_cast<float>(u) - cx) * inv_fx * z;
        const float py = (static_cast<float>(v) - cy) * inv_fy * z;
        label = K;
        float best = std::numeric_limits<float>::max();
        for (int sy = wy0; sy <= wy1; ++sy) {
          for (int sx = std::max(0, wx - 1); sx <= std::min(image.width - 1, wx + 1); ++sx) {
            const int i = sy * image.width + sx;
            if (working_label[i] == K) continue;
            const float dx = px - image.x[i], dy = py - image.y[i], dz = z - image.z[i];
            const float d2 = dx * dx + dy * dy + dz * dz;
            if (d2 < best) {
              best = d2;
              label = working_label[i];
            }
          }
        }
        if (label == K) label = nearestCentre(centres, px, py, z, &best);
      }
      label_row[u] = label;
      ++result.pixel_counts[label];
    }
  }
  return result;
}

}  // namespace ltlo::segmentation
