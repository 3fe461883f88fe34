#include "ltlo/segmentation/depth_kmeans.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include <Eigen/Eigenvalues>

#include "ltlo/core/assert.h"

namespace ltlo::segmentation {

namespace {

constexpr int kMaxCandidates = 9;  // clusters of the 3x3 samples around a pixel's block

inline bool validDepth(float z) { return z > 0.0f && z < std::numeric_limits<float>::infinity(); }

}  // namespace

struct detail::KMeansBuffers {
  std::vector<float> x_norm, y_norm;  // (u - cx) / fx per column, (v - cy) / fy per row
  // Samples with depth (structure of arrays) and the grid of blocks they come from.
  std::vector<float> sx, sy, sz;
  std::vector<int> sample_of_block;  // -1 = the block has no pixel with depth
  std::vector<std::uint8_t> sample_label;
  std::vector<char> used;
  // Centres as structure of arrays with |c|^2: the nearest centre of p minimises |c|^2 - 2 p.c.
  std::vector<float> cx, cy, cz, cn;
  std::vector<double> sum_x, sum_y, sum_z;
  std::vector<int> count;
  // Per block: the distinct clusters of the samples in the 3x3 blocks around it.
  std::vector<std::uint8_t> candidates;
  std::vector<std::uint8_t> num_candidates;
  std::vector<int> boundary_pairs;  // K x K upper triangle used
  std::vector<char> smooth_pair;    // K x K: the two clusters' planes meet without a crease
  double cos_crease = 0.8;

  void setCentre(int k, float x, float y, float z) {
    cx[k] = x;
    cy[k] = y;
    cz[k] = z;
    cn[k] = x * x + y * y + z * z;
  }
  // Nearest of all `num_centres` centres to p; *d2 = its squared distance.
  int nearestCentre(int num_centres, float px, float py, float pz, float* d2) const {
    float d[kMaxClusters];
    const float px2 = 2.0f * px, py2 = 2.0f * py, pz2 = 2.0f * pz;
    for (int k = 0; k < num_centres; ++k) d[k] = cn[k] - (px2 * cx[k] + py2 * cy[k] + pz2 * cz[k]);
    int best = 0;
    for (int k = 1; k < num_centres; ++k) best = d[k] < d[best] ? k : best;
    *d2 = d[best] + px * px + py * py + pz * pz;
    return best;
  }
};

namespace {

/// A cluster's plane normal is trusted when the smallest axis of its sample scatter is at most this
/// share of the middle one (variance ratio): a flat patch, not a corner or a curved blob.
constexpr double kPlanarVarianceRatio = 0.1;

/// smooth_pair[a * K + b]: clusters a and b lie on one smooth surface (their plane normals differ by
/// less than the crease angle, or one of them is not planar). From the samples' labels.
void smoothPairs(int K, detail::KMeansBuffers* buffers) {
  detail::KMeansBuffers& b = *buffers;
  std::vector<Mat3> scatter(static_cast<std::size_t>(K), Mat3::Zero());
  std::vector<Vec3> mean(static_cast<std::size_t>(K), Vec3::Zero());
  std::vector<int> count(static_cast<std::size_t>(K), 0);
  const int num_samples = static_cast<int>(b.sx.size());
  for (int i = 0; i < num_samples; ++i) {
    const int k = b.sample_label[i];
    const Vec3 d(b.sx[i] - b.cx[k], b.sy[i] - b.cy[k], b.sz[i] - b.cz[k]);
    scatter[k] += d * d.transpose();
    ++count[k];
  }
  std::vector<Vec3> normal(static_cast<std::size_t>(K), Vec3::Zero());
  std::vector<char> planar(static_cast<std::size_t>(K), 0);
  for (int k = 0; k < K; ++k) {
    if (count[k] < 3) continue;
    const Eigen::SelfAdjointEigenSolver<Mat3> eigen(scatter[k]);  // eigenvalues ascending
    planar[k] = eigen.eigenvalues()(0) <= kPlanarVarianceRatio * eigen.eigenvalues()(1);
    normal[k] = eigen.eigenvectors().col(0);
  }
  b.smooth_pair.assign(static_cast<std::size_t>(K) * K, 1);
  for (int a = 0; a < K; ++a) {
    for (int c = a + 1; c < K; ++c) {
      if (!planar[a] || !planar[c]) continue;
      const bool smooth = std::abs(normal[a].dot(normal[c])) >= b.cos_crease;
      b.smooth_pair[static_cast<std::size_t>(a) * K + c] = smooth;
      b.smooth_pair[static_cast<std::size_t>(c) * K + a] = smooth;
    }
  }
}


/// The sample blocks of a depth image: step_px x step_px pixels each, cols x rows of them (the last
/// column and row cut by the image's border).
struct BlockGrid {
  int step_px = 1;
  int cols = 0;
  int rows = 0;
};

/// x_norm = (u - cx) / fx per column, y_norm = (v - cy) / fy per row.
void normalisedCoordinates(const PinholeCamera& camera, int w, int h, detail::KMeansBuffers* buffers) {
  detail::KMeansBuffers& b = *buffers;
  b.x_norm.resize(w);
  b.y_norm.resize(h);
  for (int u = 0; u < w; ++u) b.x_norm[u] = static_cast<float>((u - camera.cx()) / camera.fx());
  for (int v = 0; v < h; ++v) b.y_norm[v] = static_cast<float>((v - camera.cy()) / camera.fy());
}

/// Samples: the centre pixel of each block, or the first pixel with depth in it (raster order;
/// never an average, so no sample floats between two surfaces).
void sampleBlocks(const cv::Mat& depth_m, const BlockGrid& grid, detail::KMeansBuffers* buffers) {
  detail::KMeansBuffers& b = *buffers;
  const int w = depth_m.cols, h = depth_m.rows;
  const int step = grid.step_px, bw = grid.cols, bh = grid.rows;
  b.sx.clear();
  b.sy.clear();
  b.sz.clear();
  b.sample_of_block.assign(static_cast<std::size_t>(bw) * bh, -1);
  for (int by = 0; by < bh; ++by) {
    const int v0 = by * step, v1 = std::min(h, v0 + step);
    for (int bx = 0; bx < bw; ++bx) {
      const int u0 = bx * step, u1 = std::min(w, u0 + step);
      int su = std::min(u0 + step / 2, u1 - 1), sv = std::min(v0 + step / 2, v1 - 1);
      float z = depth_m.ptr<float>(sv)[su];
      for (int v = v0; v < v1 && !validDepth(z); ++v) {
        const float* row = depth_m.ptr<float>(v);
        for (int u = u0; u < u1; ++u) {
          if (validDepth(row[u])) {
            su = u;
            sv = v;
            z = row[u];
            break;
          }
        }
      }
      if (!validDepth(z)) continue;
      b.sample_of_block[static_cast<std::size_t>(by) * bw + bx] = static_cast<int>(b.sx.size());
      b.sx.push_back(b.x_norm[su] * z);
      b.sy.push_back(b.y_norm[sv] * z);
      b.sz.push_back(z);
    }
  }
}

/// The block nearest to block (cu, cv) (Chebyshev rings, then squared distance) that has a sample
/// and is not a seed yet; -1 when none is left.
int nearestFreeBlock(int cu, int cv, const BlockGrid& grid, const detail::KMeansBuffers& b) {
  const int bw = grid.cols, bh = grid.rows;
  int best = -1;
  long best_d2 = std::numeric_limits<long>::max();
  for (int r = 0; best < 0 && r < std::max(bw, bh); ++r) {
    for (int y = std::max(0, cv - r); y <= std::min(bh - 1, cv + r); ++y) {
      const bool edge_row = y == cv - r || y == cv + r;
      const int x_step = edge_row ? 1 : std::max(1, 2 * r);
      for (int x = cu - r; x <= cu + r; x += x_step) {
        if (x < 0 || x >= bw) continue;
        const int block = y * bw + x;
        if (b.sample_of_block[block] < 0 || b.used[block]) continue;
        const long d2 = static_cast<long>(x - cu) * (x - cu) + static_cast<long>(y - cv) * (y - cv);
        if (d2 < best_d2) {
          best_d2 = d2;
          best = block;
        }
      }
    }
  }
  return best;
}

/// Seeds on a uniform grid of blocks (rows x cols >= K, K cells picked evenly); a cell without
/// a sample moves to the nearest block (Chebyshev rings) with a sample not yet a seed.
void seedCentres(int K, const BlockGrid& grid, detail::KMeansBuffers* buffers) {
  detail::KMeansBuffers& b = *buffers;
  const int bw = grid.cols, bh = grid.rows;
  const int grid_rows = std::max(1, static_cast<int>(std::lround(std::sqrt(K * static_cast<double>(bh) / bw))));
  const int grid_cols = (K + grid_rows - 1) / grid_rows;
  const int num_cells = grid_rows * grid_cols;
  b.used.assign(b.sample_of_block.size(), 0);
  for (int s = 0; s < K; ++s) {
    const int cell = static_cast<int>((s + 0.5) * num_cells / K);
    const int cu = static_cast<int>((cell % grid_cols + 0.5) * bw / grid_cols);
    const int cv = static_cast<int>((cell / grid_cols + 0.5) * bh / grid_rows);
    const int best = nearestFreeBlock(cu, cv, grid, b);
    LTLO_ASSERT(best >= 0, "no free sample for seed " << s);
    b.used[best] = 1;
    const int i = b.sample_of_block[best];
    b.setCentre(s, b.sx[i], b.sy[i], b.sz[i]);
  }
}

/// Lloyd iterations on the samples.
void lloydIterations(int K, int iterations, detail::KMeansBuffers* buffers) {
  detail::KMeansBuffers& b = *buffers;
  const int num_samples = static_cast<int>(b.sx.size());
  for (int iteration = 0; iteration < iterations; ++iteration) {
    b.sum_x.assign(K, 0.0);
    b.sum_y.assign(K, 0.0);
    b.sum_z.assign(K, 0.0);
    b.count.assign(K, 0);
    float worst_d2 = -1.0f;
    int worst = 0;
    for (int i = 0; i < num_samples; ++i) {
      float d2;
      const int k = b.nearestCentre(K, b.sx[i], b.sy[i], b.sz[i], &d2);
      b.sum_x[k] += b.sx[i];
      b.sum_y[k] += b.sy[i];
      b.sum_z[k] += b.sz[i];
      ++b.count[k];
      if (d2 > worst_d2) {
        worst_d2 = d2;
        worst = i;
      }
    }
    const bool last = iteration + 1 == iterations;
    bool reseeded = false;
    for (int k = 0; k < K; ++k) {
      if (b.count[k] > 0) {
        b.setCentre(k, static_cast<float>(b.sum_x[k] / b.count[k]), static_cast<float>(b.sum_y[k] / b.count[k]),
                    static_cast<float>(b.sum_z[k] / b.count[k]));
      } else if (!last && !reseeded) {
        // An empty cluster restarts at the sample worst served by its centre (keeps K clusters).
        b.setCentre(k, b.sx[worst], b.sy[worst], b.sz[worst]);
        reseeded = true;
      }
    }
  }
}

/// Each sample's label: its nearest centre.
void labelSamples(int K, detail::KMeansBuffers* buffers) {
  detail::KMeansBuffers& b = *buffers;
  const int num_samples = static_cast<int>(b.sx.size());
  b.sample_label.resize(num_samples);
  for (int i = 0; i < num_samples; ++i) {
    float d2;
    b.sample_label[i] = static_cast<std::uint8_t>(b.nearestCentre(K, b.sx[i], b.sy[i], b.sz[i], &d2));
  }
}

/// Candidate clusters of each block: those of the samples in the 3x3 blocks around it.
void candidateClusters(const BlockGrid& grid, detail::KMeansBuffers* buffers) {
  detail::KMeansBuffers& b = *buffers;
  const int bw = grid.cols, bh = grid.rows;
  b.candidates.resize(b.sample_of_block.size() * kMaxCandidates);
  b.num_candidates.assign(b.sample_of_block.size(), 0);
  for (int by = 0; by < bh; ++by) {
    for (int bx = 0; bx < bw; ++bx) {
      const std::size_t block = static_cast<std::size_t>(by) * bw + bx;
      std::uint8_t* list = &b.candidates[block * kMaxCandidates];
      int n = 0;
      for (int y = std::max(0, by - 1); y <= std::min(bh - 1, by + 1); ++y) {
        for (int x = std::max(0, bx - 1); x <= std::min(bw - 1, bx + 1); ++x) {
          const int i = b.sample_of_block[static_cast<std::size_t>(y) * bw + x];
          if (i < 0) continue;
          const std::uint8_t k = b.sample_label[i];
          if (std::find(list, list + n, k) == list + n) list[n++] = k;
        }
      }
      b.num_candidates[block] = static_cast<std::uint8_t>(n);
    }
  }
}

/// The label of a pixel with depth z_m whose normalised coordinates are (x_norm, y_norm), in
/// `block`: its nearest centre among the block's candidate clusters (among all centres when the
/// block has none). K (no depth) when no candidate is at a finite distance.
std::uint8_t labelOfPixel(const detail::KMeansBuffers& b, int K, std::size_t block, float x_norm, float y_norm,
                          float z) {
  std::uint8_t label = static_cast<std::uint8_t>(K);
  const int n = b.num_candidates[block];
  if (n == 1) {
    label = b.candidates[block * kMaxCandidates];
  } else {
    const float px = x_norm * z, py = y_norm * z;
    float d2;
    if (n == 0) {
      label = static_cast<std::uint8_t>(b.nearestCentre(K, px, py, z, &d2));
    } else {
      const std::uint8_t* list = &b.candidates[block * kMaxCandidates];
      float best = std::numeric_limits<float>::max();
      for (int c = 0; c < n; ++c) {
        const int k = list[c];
        const float dx = px - b.cx[k], dy = py - b.cy[k], dz = z - b.cz[k];
        const float d = dx * dx + dy * dy + dz * dz;
        if (d < best) {
          best = d;
          label = list[c];
        }
      }
    }
  }
  return label;
}

/// Counts the boundary pixel pairs of V_i (buffers' boundary_pairs, K x K upper triangle): two
/// different depth clusters on one smooth surface whose depths across the boundary differ by less
/// than DepthKMeansOptions::gapThreshold (evaluated in float).
class BoundaryPairCounter {
 public:
  BoundaryPairCounter(int K, const DepthKMeansOptions& options, detail::KMeansBuffers* buffers)
      : K_(K),
        no_depth_(static_cast<std::uint8_t>(K)),
        gap0_(static_cast<float>(options.gap_at_zero_m)),
        gap_growth_(static_cast<float>(options.gap_growth_per_m)),
        gap_max_(static_cast<float>(options.max_gap_m)),
        buffers_(*buffers) {}

  /// Pixel pair of labels a and c at depths za and zc, m.
  void operator()(std::uint8_t a, std::uint8_t c, float za, float zc) {
    const int K = K_;
    if (a == c || a == no_depth_ || c == no_depth_ || !buffers_.smooth_pair[static_cast<std::size_t>(a) * K + c]) return;
    const float z_mean = 0.5f * (za + zc);
    if (std::abs(za - zc) < std::min(gap_max_, gap0_ + gap_growth_ * z_mean * z_mean)) {
      ++buffers_.boundary_pairs[static_cast<std::size_t>(std::min(a, c)) * K + std::max(a, c)];
    }
  }

 private:
  const int K_;
  const std::uint8_t no_depth_;
  const float gap0_;
  const float gap_growth_;
  const float gap_max_;
  detail::KMeansBuffers& buffers_;
};

/// One pass over all pixels: the label (nearest centre among the block's candidates), the pixel
/// counts and the boundary pairs of V_i with the left and upper neighbours.
void labelPixels(const cv::Mat& depth_m, const BlockGrid& grid, int K, const DepthKMeansOptions& options,
                 detail::KMeansBuffers* buffers, DepthClusters* out) {
  detail::KMeansBuffers& b = *buffers;
  const int w = depth_m.cols, h = depth_m.rows;
  const int step = grid.step_px, bw = grid.cols;
  b.boundary_pairs.assign(static_cast<std::size_t>(std::max(K, 1)) * std::max(K, 1), 0);
  if (K == 0) b.smooth_pair.assign(1, 1);
  const std::uint8_t no_depth = static_cast<std::uint8_t>(K);
  BoundaryPairCounter link(K, options, &b);
  int* counts = out->pixel_counts.data();
  for (int v = 0; v < h; ++v) {
    const float* depth_row = depth_m.ptr<float>(v);
    std::uint8_t* label_row = out->labels.ptr<std::uint8_t>(v);
    const std::size_t block_row = static_cast<std::size_t>(v / step) * bw;
    const float yn = b.y_norm[v];
    for (int u = 0; u < w; ++u) {
      const float z = depth_row[u];
      std::uint8_t label = no_depth;
      if (validDepth(z) && K > 0) {
        label = labelOfPixel(b, K, block_row + static_cast<std::size_t>(u / step), b.x_norm[u], yn, z);
      }
      label_row[u] = label;
      ++counts[label];
      if (label == no_depth) continue;
      if (u > 0) link(label_row[u - 1], label, depth_row[u - 1], z);
      if (v > 0) link(out->labels.ptr<std::uint8_t>(v - 1)[u], label, depth_m.ptr<float>(v - 1)[u], z);
    }
  }
}

/// V_i from the boundary pairs: each linked pair once (a < c), sorted by (a, c).
void boundaryEdges(int K, const detail::KMeansBuffers& b, DepthClusters* out) {
  for (int a = 0; a < K; ++a) {
    for (int c = a + 1; c < K; ++c) {
      const int pairs = b.boundary_pairs[static_cast<std::size_t>(a) * K + c];
      if (pairs > 0) out->edges.push_back({a, c, pairs});
    }
  }
}
}  // namespace

DepthKMeansOptions DepthKMeansOptions::from(const SegmentationOptions& segmentation) {
  DepthKMeansOptions options;
  options.num_clusters = segmentation.num_clusters;
  options.kmeans_iterations = segmentation.kmeans_iterations;
  options.max_gap_m = segmentation.max_neighbour_gap_m;
  return options;
}

double DepthKMeansOptions::gapThreshold(double z_m) const {
  return std::min(max_gap_m, gap_at_zero_m + gap_growth_per_m * z_m * z_m);
}

DepthKMeans::DepthKMeans(const DepthKMeansOptions& options)
    : options_(options), buffers_(std::make_unique<detail::KMeansBuffers>()) {
  buffers_->cos_crease = std::cos(options.max_crease_angle_rad);
  LTLO_ASSERT(options.num_clusters >= 1 && options.num_clusters <= kMaxClusters,
              "num_clusters = " << options.num_clusters << ", expected [1, " << kMaxClusters << "] (8-bit labels)");
  LTLO_ASSERT(options.kmeans_iterations >= 1, "kmeans_iterations = " << options.kmeans_iterations);
  LTLO_ASSERT(options.sample_step_px >= 1, "sample_step_px = " << options.sample_step_px);
}

DepthKMeans::~DepthKMeans() = default;
DepthKMeans::DepthKMeans(DepthKMeans&&) noexcept = default;
DepthKMeans& DepthKMeans::operator=(DepthKMeans&&) noexcept = default;

void DepthKMeans::cluster(const cv::Mat& depth_m, const PinholeCamera& camera, DepthClusters* out) {
  LTLO_ASSERT(depth_m.type() == CV_32F, "depth type " << depth_m.type() << ", expected CV_32F");
  LTLO_ASSERT(depth_m.cols == camera.width() && depth_m.rows == camera.height(),
              "depth " << depth_m.cols << "x" << depth_m.rows << ", camera " << camera.width() << "x"
                       << camera.height());
  detail::KMeansBuffers& b = *buffers_;
  const int w = depth_m.cols, h = depth_m.rows;
  const int step = std::max(1, std::min({options_.sample_step_px, w, h}));
  const BlockGrid grid{step, (w + step - 1) / step, (h + step - 1) / step};

  normalisedCoordinates(camera, w, h, &b);
  sampleBlocks(depth_m, grid, &b);
  const int num_samples = static_cast<int>(b.sx.size());
  const int K = std::min(options_.num_clusters, num_samples);
  out->num_clusters = K;
  if (out->labels.type() != CV_8U || out->labels.rows != h || out->labels.cols != w) out->labels.create(h, w, CV_8U);
  out->pixel_counts.assign(static_cast<std::size_t>(K) + 1, 0);
  out->edges.clear();
  out->centroids_c.clear();

  b.cx.resize(std::max(K, 1));
  b.cy.resize(std::max(K, 1));
  b.cz.resize(std::max(K, 1));
  b.cn.resize(std::max(K, 1));
  if (K > 0) {
    seedCentres(K, grid, &b);
    lloydIterations(K, options_.kmeans_iterations, &b);
    labelSamples(K, &b);
    for (int k = 0; k < K; ++k) out->centroids_c.emplace_back(b.cx[k], b.cy[k], b.cz[k]);
    smoothPairs(K, &b);
    candidateClusters(grid, &b);
  }
  labelPixels(depth_m, grid, K, options_, &b, out);
  boundaryEdges(K, b, out);
}

}  // namespace ltlo::segmentation
