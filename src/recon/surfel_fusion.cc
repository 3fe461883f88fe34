#include "ltlo/recon/surfel_fusion.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>

#include "ltlo/core/assert.h"
#include "ltlo/core/timing.h"
#include "measurement.h"
#include "surfel_map.h"
#include "worker_pool.h"

namespace ltlo::recon {
namespace {

constexpr uint64_t kEmptyPixel = ~uint64_t{0};
constexpr int kPartShift = 28;  // render threads per id: up to 16; surfels per part: 268 M
constexpr uint32_t kIndexMask = (uint32_t{1} << kPartShift) - 1;

// Cells of 0.5 m: a VGA frame of a room touches a few hundred of them, a 45 s sequence a few
// thousand; the margin covers surfels drifting out of their creation cell while fused.
constexpr float kCellSizeM = 0.5f;
constexpr float kCellMarginM = 0.1f;
// A measurement this much coarser than the surfel (radius ratio) only adds confidence
// (ElasticFusion's rule: a distant view does not blur detail seen from close up).
constexpr float kCoarserRadiusRatio = 1.5f;

// Index map: twice the fusion grid's resolution (each fusion pixel owns 2 x 2 index pixels).
PinholeCamera indexCamera(const PinholeCamera& fusion) {
  return PinholeCamera(2.0 * fusion.fx(), 2.0 * fusion.fy(), 2.0 * (fusion.cx() + 0.5) - 0.5,
                       2.0 * (fusion.cy() + 0.5) - 0.5, 2 * fusion.width(), 2 * fusion.height());
}

// Inward unit normals of the four side planes of the camera's frustum (camera frame): a point p
// is inside when every n . p >= 0.
std::array<Eigen::Vector3f, 4> frustumPlanes(const PinholeCamera& camera) {
  const float fx = static_cast<float>(camera.fx()), fy = static_cast<float>(camera.fy());
  const float left = static_cast<float>(camera.cx() + 0.5);
  const float right = static_cast<float>(camera.width() - 0.5 - camera.cx());
  const float top = static_cast<float>(camera.cy() + 0.5);
  const float bottom = static_cast<float>(camera.height() - 0.5 - camera.cy());
  return {
      Eigen::Vector3f(fx, 0.0f, left).normalized(), Eigen::Vector3f(-fx, 0.0f, right).normalized(),
      Eigen::Vector3f(0.0f, fy, top).normalized(), Eigen::Vector3f(0.0f, -fy, bottom).normalized()};
}

// R * p + t without Eigen's out-of-line product kernels (hot loops).
inline Eigen::Vector3f transform(const Eigen::Matrix3f& R, const Eigen::Vector3f& p,
                                 const Eigen::Vector3f& t) {
  return Eigen::Vector3f(R(0, 0) * p.x() + R(0, 1) * p.y() + R(0, 2) * p.z() + t.x(),
                         R(1, 0) * p.x() + R(1, 1) * p.y() + R(1, 2) * p.z() + t.y(),
                         R(2, 0) * p.x() + R(2, 1) * p.y() + R(2, 2) * p.z() + t.z());
}
inline Eigen::Vector3f rotate(const Eigen::Matrix3f& R, const Eigen::Vector3f& n) {
  return transform(R, n, Eigen::Vector3f::Zero());
}

}  // namespace

struct SurfelFusion::Impl {
  PinholeCamera camera;
  PinholeCamera fusion_camera;
  PinholeCamera index_camera;
  ReconOptions options;
  std::array<Eigen::Vector3f, 4> planes;
  float cos_assoc_angle = 0.0f;
  SurfelMap map{kCellSizeM};
  FusionTotals totals;
  TimingStats timing;
  bool started = false;
  double t0_s = 0.0;

  // Per-frame buffers, reused.
  Measurement own_measurement;        // integrate(frame) measures here
  const Measurement* measurement = nullptr;  // the frame being fused
  std::unique_ptr<WorkerPool> pool;
  // Index map: per index pixel the nearest surfel as (camera depth bits << 32 | id), written with
  // an atomic minimum by the render threads (positive floats order like their bit patterns); id =
  // part << kPartShift | index into rendered_by_part[part]. (Copying the winners' data into
  // pixel-ordered arrays instead of following the ids measured 10 % slower: the copy costs as
  // many cache misses as it saves.)
  std::unique_ptr<std::atomic<uint64_t>[]> index_map;
  std::size_t index_pixels = 0;
  std::vector<std::vector<Surfel*>> rendered_by_part;
  std::vector<Surfel*> rendered;     // all parts, in part order
  std::vector<int32_t> part_offset;  // first index of each part in `rendered`
  std::vector<uint8_t> fused;        // per rendered surfel: took a measurement this frame
  std::vector<int> visible_cells;
  std::vector<std::vector<Surfel>> created_by_part;
  std::vector<FusionFrameStats> stats_by_part;

  /// Index into `rendered` of the surfel at index pixel q, -1 when empty.
  int32_t idAt(std::size_t q) const {
    const uint64_t value = index_map[q].load(std::memory_order_relaxed);
    if (value == kEmptyPixel) return -1;
    const uint32_t id = static_cast<uint32_t>(value);
    return part_offset[id >> kPartShift] + static_cast<int32_t>(id & kIndexMask);
  }
  struct Pose {
    const Eigen::Matrix3f& R_w_c;
    const Eigen::Vector3f& t_w_c;
    float t_rel_s;
    bool with_colour;  // false: a geometry-only frame (no colour fused, no surfel made)
  };
  std::vector<uint8_t> ring_pending;  // per fusion pixel: no surfel in its own block
  /// One fusion row of associateAndFuse(): phase 1 (own block) or phase 2 (ring).
  void fuseRow(int j, const Pose& pose, bool ring, int part);

  void renderIndexMap(const Eigen::Matrix3f& R_c_w, const Eigen::Vector3f& t_c_w);
  void associateAndFuse(const Eigen::Matrix3f& R_w_c, const Eigen::Vector3f& t_w_c, float t_rel_s,
                        bool with_colour, FusionFrameStats* stats);
  void removeFreeSpaceViolations(const Eigen::Matrix3f& R_c_w, const Eigen::Vector3f& t_c_w,
                                 FusionFrameStats* stats);
  void cleanVisibleCells(float t_rel_s, FusionFrameStats* stats);
};

SurfelFusion::SurfelFusion(const PinholeCamera& camera, const ReconOptions& options, int threads)
    : impl_(std::make_unique<Impl>()) {
  options.validate();
  LTLO_ASSERT(threads >= 1 && threads <= 16, "fusion threads " << threads);
  Impl& im = *impl_;
  im.pool = std::make_unique<WorkerPool>(threads - 1);
  im.camera = camera;
  im.options = options;
  im.fusion_camera = fusionCamera(camera, options.downsample);
  LTLO_ASSERT(im.fusion_camera.width() >= 3 && im.fusion_camera.height() >= 3,
              "fusion grid " << im.fusion_camera.width() << "x" << im.fusion_camera.height());
  im.index_camera = indexCamera(im.fusion_camera);
  im.planes = frustumPlanes(im.fusion_camera);
  im.cos_assoc_angle = static_cast<float>(std::cos(options.assoc_max_angle_deg * M_PI / 180.0));
  im.index_pixels = static_cast<std::size_t>(im.index_camera.width()) * im.index_camera.height();
  im.index_map = std::make_unique<std::atomic<uint64_t>[]>(im.index_pixels);
  im.rendered_by_part.resize(threads);
  im.created_by_part.resize(threads);
  im.stats_by_part.resize(threads);
}

SurfelFusion::~SurfelFusion() = default;

void SurfelFusion::Impl::renderIndexMap(const Eigen::Matrix3f& R_c_w,
                                        const Eigen::Vector3f& t_c_w) {
  const int width = index_camera.width();
  const int height = index_camera.height();
  pool->parallelFor(static_cast<int>(index_pixels), [&](int begin, int end, int) {
    for (int k = begin; k < end; ++k) index_map[k].store(kEmptyPixel, std::memory_order_relaxed);
  });
  visible_cells.clear();

  // Surfels farther than the farthest measurement plus its window can neither take a measurement
  // nor be seen through.
  const float z_near = 0.5f * static_cast<float>(options.min_depth_m);
  const float z_far = static_cast<float>(options.max_depth_m) +
                      associationWindowM(options, static_cast<float>(options.max_depth_m));
  const float cell_radius = 0.5f * std::sqrt(3.0f) * map.cellSizeM() + kCellMarginM;
  std::vector<SurfelMap::Cell>& cells = map.cells();
  std::vector<std::size_t> cumulative_surfels;  // split the visible cells by surfel count
  std::size_t total = 0;
  for (int c = 0; c < static_cast<int>(cells.size()); ++c) {
    const Eigen::Vector3f centre_c = transform(R_c_w, cells[c].centre_w, t_c_w);
    if (centre_c.z() + cell_radius < z_near || centre_c.z() - cell_radius > z_far) continue;
    bool inside = true;
    for (const Eigen::Vector3f& n : planes) inside = inside && n.dot(centre_c) >= -cell_radius;
    if (!inside) continue;
    visible_cells.push_back(c);
    total += cells[c].surfels.size();
    cumulative_surfels.push_back(total);
  }

  const float fx = static_cast<float>(index_camera.fx());
  const float fy = static_cast<float>(index_camera.fy());
  const float cx = static_cast<float>(index_camera.cx());
  const float cy = static_cast<float>(index_camera.cy());
  const int parts = pool->parts();
  pool->parallelFor(parts, [&](int part_begin, int part_end, int) {
    for (int part = part_begin; part < part_end; ++part) {
      std::vector<Surfel*>& mine = rendered_by_part[part];
      mine.clear();
      // Cells whose cumulative surfel count falls in this part's share.
      const std::size_t from = total * part / parts, to = total * (part + 1) / parts;
      const auto first =
          std::upper_bound(cumulative_surfels.begin(), cumulative_surfels.end(), from);
      const auto last = std::upper_bound(cumulative_surfels.begin(), cumulative_surfels.end(), to);
      for (auto it = first; it != last && it != cumulative_surfels.end(); ++it) {
        if (*it <= from) continue;
        for (Surfel& s : cells[visible_cells[it - cumulative_surfels.begin()]].surfels) {
          const Eigen::Vector3f p = transform(R_c_w, s.position_w, t_c_w);
          if (p.z() < z_near || p.z() > z_far) continue;
          if (rotate(R_c_w, s.normal_w).dot(p) > 0.0f) continue;  // seen from behind
          const float inv_z = 1.0f / p.z();
          const int u = static_cast<int>(std::floor(fx * p.x() * inv_z + cx + 0.5f));
          const int v = static_cast<int>(std::floor(fy * p.y() * inv_z + cy + 0.5f));
          if (u < 0 || v < 0 || u >= width || v >= height) continue;
          uint32_t z_bits = 0;
          const float z = p.z();
          std::memcpy(&z_bits, &z, 4);
          const uint64_t value = (static_cast<uint64_t>(z_bits) << 32) |
                                 (static_cast<uint32_t>(part) << kPartShift) |
                                 static_cast<uint32_t>(mine.size());
          std::atomic<uint64_t>& pixel = index_map[static_cast<std::size_t>(v) * width + u];
          uint64_t current = pixel.load(std::memory_order_relaxed);
          bool won = false;
          while (value < current) {  // nearer (ties: lower part, then earlier surfel)
            if (pixel.compare_exchange_weak(current, value, std::memory_order_relaxed)) {
              won = true;
              break;
            }
          }
          if (won) mine.push_back(&s);
        }
      }
    }
  });
  rendered.clear();
  part_offset.assign(parts, 0);
  for (int part = 0; part < parts; ++part) {
    part_offset[part] = static_cast<int32_t>(rendered.size());
    rendered.insert(rendered.end(), rendered_by_part[part].begin(), rendered_by_part[part].end());
  }
  fused.assign(rendered.size(), 0);
}

// Association in two phases, so that the result depends neither on the order of the pixels nor
// on the number of threads:
//   1. every fusable pixel takes the best compatible surfel centred in its own 2 x 2 index pixels
//      (a surfel is in one index pixel, so in one pixel's block: no conflicts);
//   2. pixels left without one look at the ring of index pixels around their block for a disc
//      that covers their point and has not taken a measurement this frame. Rings of fusion rows j
//      and j + 1 overlap, of rows j and j + 2 never: even rows run first, then odd rows, each set
//      split over the threads.
void SurfelFusion::Impl::associateAndFuse(const Eigen::Matrix3f& R_w_c,
                                          const Eigen::Vector3f& t_w_c, float t_rel_s,
                                          bool with_colour, FusionFrameStats* stats) {
  const int height = measurement->height;
  const int parts = pool->parts();
  for (int part = 0; part < parts; ++part) {
    created_by_part[part].clear();
    stats_by_part[part] = FusionFrameStats();
  }
  ring_pending.assign(measurement->state.size(), 0);
  const Pose pose{R_w_c, t_w_c, t_rel_s, with_colour};
  pool->parallelFor(height, [&](int begin, int end, int part) {
    for (int j = begin; j < end; ++j) fuseRow(j, pose, /*ring=*/false, part);
  });
  for (int parity = 0; parity < 2; ++parity) {
    const int rows = (height - parity + 1) / 2;
    pool->parallelFor(rows, [&](int begin, int end, int part) {
      for (int r = begin; r < end; ++r) fuseRow(2 * r + parity, pose, /*ring=*/true, part);
    });
  }
  for (int part = 0; part < parts; ++part) {
    stats->merged += stats_by_part[part].merged;
    stats->covered += stats_by_part[part].covered;
    stats->created += static_cast<int>(created_by_part[part].size());
  }
}

void SurfelFusion::Impl::fuseRow(int j, const Pose& pose, bool ring, int part) {
  const Measurement& m = *measurement;
  const int index_width = index_camera.width();
  const int index_height = index_camera.height();
  FusionFrameStats& stats = stats_by_part[part];
  // The surfels a row looks at lie scattered over the model, and their cache misses were half of
  // the association's time: request them all first, so that the memory system fetches them in
  // parallel, then do the arithmetic (a surfel may straddle two cache lines).
  const int v_begin = ring ? std::max(0, 2 * j - 1) : 2 * j;
  const int v_end = ring ? std::min(index_height, 2 * j + 3) : 2 * j + 2;
  for (int i = 0; i < m.width; ++i) {
    const std::size_t k = static_cast<std::size_t>(j) * m.width + i;
    if (m.state[k] != PixelState::kFusable || (ring && !ring_pending[k])) continue;
    const int u_begin = ring ? std::max(0, 2 * i - 1) : 2 * i;
    const int u_end = ring ? std::min(index_width, 2 * i + 3) : 2 * i + 2;
    for (int v = v_begin; v < v_end; ++v) {
      for (int u = u_begin; u < u_end; ++u) {
        const int32_t id = idAt(static_cast<std::size_t>(v) * index_width + u);
        if (id < 0) continue;
        const char* surfel = reinterpret_cast<const char*>(rendered[id]);
        __builtin_prefetch(surfel);
        __builtin_prefetch(surfel + sizeof(Surfel) - 1);
      }
    }
  }
  for (int i = 0; i < m.width; ++i) {
    const std::size_t k = static_cast<std::size_t>(j) * m.width + i;
    if (m.state[k] != PixelState::kFusable || (ring && !ring_pending[k])) continue;
    const Eigen::Vector3f p_w = transform(pose.R_w_c, m.point_c[k], pose.t_w_c);
    const Eigen::Vector3f n_w = rotate(pose.R_w_c, m.normal_c[k]);
    const float window = associationWindowM(options, m.point_c[k].z());
    int32_t best = -1;  // into `rendered`
    if (!ring) {
      // The 2 x 2 index pixels of this fusion pixel: the most confident compatible surfel.
      for (int dv = 0; dv < 2; ++dv) {
        const std::size_t row = static_cast<std::size_t>(2 * j + dv) * index_width + 2 * i;
        for (std::size_t q = row; q < row + 2; ++q) {
          const int32_t id = idAt(q);
          if (id < 0) continue;
          const Surfel& s = *rendered[id];
          if (std::abs(s.normal_w.dot(p_w - s.position_w)) > window) continue;
          if (s.normal_w.dot(n_w) < cos_assoc_angle) continue;
          if (best < 0 || s.confidence > rendered[best]->confidence) best = id;
        }
      }
      if (best < 0) {
        ring_pending[k] = 1;
        continue;
      }
    } else {
      // No surfel centre in this pixel: does a disc centred in the ring of index pixels around
      // it cover the point? (Projected surfel centres shift by sub-pixel amounts between views,
      // which leaves some blocks empty and others with two; without this test every empty block
      // would add a surfel on top of a disc. A disc's radius is about 1.4 index pixels at the
      // distance it was made from, so one ring of index pixels suffices.)
      bool covered = false;
      for (int v = std::max(0, 2 * j - 1); v < std::min(index_height, 2 * j + 3); ++v) {
        for (int u = std::max(0, 2 * i - 1); u < std::min(index_width, 2 * i + 3); ++u) {
          const int32_t id = idAt(static_cast<std::size_t>(v) * index_width + u);
          if (id < 0) continue;
          const Surfel& s = *rendered[id];
          const Eigen::Vector3f d = p_w - s.position_w;
          const float along = s.normal_w.dot(d);
          if (std::abs(along) > window || s.normal_w.dot(n_w) < cos_assoc_angle) continue;
          if ((d - along * s.normal_w).squaredNorm() > s.radius_m * s.radius_m) continue;
          covered = true;
          if (!fused[id] && (best < 0 || s.confidence > rendered[best]->confidence)) best = id;
        }
      }
      if (covered && best < 0) {  // its surfel took a measurement this frame already
        ++stats.covered;
        continue;
      }
    }
    const float alpha = m.alpha[k];
    const float radius = m.radius_m[k];
    if (best >= 0) {
      fused[best] = 1;
      Surfel& s = *rendered[best];
      if (radius <= kCoarserRadiusRatio * s.radius_m) {
        // Keller et al. 2013, Eq. 4: confidence-weighted running averages.
        const float w_old = s.confidence / (s.confidence + alpha);
        const float w_new = 1.0f - w_old;
        s.position_w = w_old * s.position_w + w_new * p_w;
        s.normal_w = (w_old * s.normal_w + w_new * n_w).normalized();
        if (pose.with_colour) s.colour_rgb = w_old * s.colour_rgb + w_new * m.colour_rgb[k];
        s.radius_m = w_old * s.radius_m + w_new * radius;
      }
      s.confidence += alpha;
      s.last_seen_s = pose.t_rel_s;
      if (s.violations > 0) --s.violations;
      ++stats.merged;
    } else if (pose.with_colour) {
      Surfel s;
      s.position_w = p_w;
      s.normal_w = n_w;
      s.radius_m = radius;
      s.confidence = alpha;
      s.colour_rgb = m.colour_rgb[k];
      s.first_seen_s = pose.t_rel_s;
      s.last_seen_s = pose.t_rel_s;
      created_by_part[part].push_back(s);
    }
  }
}

void SurfelFusion::Impl::removeFreeSpaceViolations(const Eigen::Matrix3f& R_c_w,
                                                   const Eigen::Vector3f& t_c_w,
                                                   FusionFrameStats* stats) {
  if (options.free_space_votes == 0) return;
  const Measurement& m = *measurement;
  const float stable = static_cast<float>(options.confidence_stable);
  const int index_width = index_camera.width();
  const int index_height = index_camera.height();
  std::vector<int> removed(pool->parts(), 0);
  // Each surfel is in one index pixel at most: the parts touch disjoint surfels.
  pool->parallelFor(index_height, [&](int v_begin, int v_end, int part) {
    for (int v = v_begin; v < v_end; ++v) {
      for (int u = 0; u < index_width; ++u) {
        const std::size_t q = static_cast<std::size_t>(v) * index_width + u;
        const int32_t id = idAt(q);
        if (id < 0 || fused[id]) continue;
        const std::size_t k = static_cast<std::size_t>(v / 2) * m.width + u / 2;
        if (m.state[k] == PixelState::kInvalid) continue;
        // Violation: the surfel lies in front of the measured surface, beyond the association
        // window along the measured normal and along the ray, so the sensor saw through it.
        const Eigen::Vector3f& p_m = m.point_c[k];
        const float window = associationWindowM(options, p_m.z());
        Surfel& s = *rendered[id];
        const Eigen::Vector3f p_s = transform(R_c_w, s.position_w, t_c_w);
        if (m.normal_c[k].dot(p_s - p_m) <= window || p_s.z() >= p_m.z() - window) continue;
        if (s.confidence >= stable && ++s.violations < options.free_space_votes) continue;
        s.confidence = -1.0f;
        ++removed[part];
      }
    }
  });
  for (int n : removed) stats->removed_free_space += n;
}

void SurfelFusion::Impl::cleanVisibleCells(float t_rel_s, FusionFrameStats* stats) {
  const float stable = static_cast<float>(options.confidence_stable);
  const float window_s = static_cast<float>(options.unstable_time_s);
  std::vector<SurfelMap::Cell>& cells = map.cells();
  std::vector<int> removed(pool->parts(), 0);
  pool->parallelFor(static_cast<int>(visible_cells.size()), [&](int begin, int end, int part) {
    for (int k = begin; k < end; ++k) {
      SurfelMap::Cell& cell = cells[visible_cells[k]];
      for (Surfel& s : cell.surfels) {
        if (s.confidence >= 0.0f && s.confidence < stable && t_rel_s - s.first_seen_s > window_s) {
          s.confidence = -1.0f;
          ++removed[part];
        }
      }
      SurfelMap::compact(&cell);
    }
  });
  for (int n : removed) stats->removed_unstable += n;
}

PreparedFrame::PreparedFrame() : measurement_(std::make_unique<Measurement>()) {}
PreparedFrame::~PreparedFrame() = default;
PreparedFrame::PreparedFrame(PreparedFrame&&) noexcept = default;
PreparedFrame& PreparedFrame::operator=(PreparedFrame&&) noexcept = default;

void SurfelFusion::prepare(const FusionFrame& frame, PreparedFrame* out) const {
  const Impl& im = *impl_;
  LTLO_ASSERT(out != nullptr && out->measurement_ != nullptr, "prepare: no (or a moved-from) out");
  computeMeasurement(frame, im.camera, im.fusion_camera, im.options, /*pool=*/nullptr,
                     out->measurement_.get());
}

FusionFrameStats SurfelFusion::integrate(const FusionFrame& frame) {
  Impl& im = *impl_;
  {
    ScopedTimer timer(im.timing, "recon.measurement");
    computeMeasurement(frame, im.camera, im.fusion_camera, im.options, im.pool.get(),
                       &im.own_measurement);
  }
  return fuseMeasured(frame, im.own_measurement);
}

FusionFrameStats SurfelFusion::integrate(const FusionFrame& frame, const PreparedFrame& prepared) {
  LTLO_ASSERT(prepared.measurement_ != nullptr && prepared.measurement_->width > 0,
              "integrate: the frame was not prepared");
  return fuseMeasured(frame, *prepared.measurement_);
}

FusionFrameStats SurfelFusion::fuseMeasured(const FusionFrame& frame, const Measurement& m) {
  Impl& im = *impl_;
  LTLO_ASSERT(m.width == im.fusion_camera.width() && m.height == im.fusion_camera.height(),
              "measurement " << m.width << "x" << m.height << " vs fusion grid "
                             << im.fusion_camera.width() << "x" << im.fusion_camera.height());
  if (!im.started) {
    im.started = true;
    im.t0_s = frame.t_s;
  }
  const float t_rel_s = static_cast<float>(frame.t_s - im.t0_s);
  FusionFrameStats stats;
  im.measurement = &m;
  stats.measured_pixels = m.num_geometry;
  stats.fused_pixels = m.num_fusable;

  const Eigen::Matrix3f R_w_c = frame.T_w_c.rotationMatrix().cast<float>();
  const Eigen::Vector3f t_w_c = frame.T_w_c.translation().cast<float>();
  const Eigen::Matrix3f R_c_w = R_w_c.transpose();
  const Eigen::Vector3f t_c_w = -(R_c_w * t_w_c);

  {
    ScopedTimer timer(im.timing, "recon.index_map");
    im.renderIndexMap(R_c_w, t_c_w);
  }
  stats.rendered = static_cast<int>(im.rendered.size());
  {
    ScopedTimer timer(im.timing, "recon.associate_fuse");
    im.associateAndFuse(R_w_c, t_w_c, t_rel_s, !frame.colour_bgr.empty(), &stats);
  }
  {
    ScopedTimer timer(im.timing, "recon.free_space");
    im.removeFreeSpaceViolations(R_c_w, t_c_w, &stats);
  }
  {
    ScopedTimer timer(im.timing, "recon.clean_insert");
    im.cleanVisibleCells(t_rel_s, &stats);
    for (const std::vector<Surfel>& created : im.created_by_part) {
      for (const Surfel& s : created) im.map.insert(s);
    }
  }

  ++im.totals.frames;
  im.totals.merged += stats.merged;
  im.totals.created += stats.created;
  im.totals.removed_unstable += stats.removed_unstable;
  im.totals.removed_free_space += stats.removed_free_space;
  im.measurement = nullptr;
  return stats;
}

std::vector<Surfel> SurfelFusion::stableSurfels() const {
  const float stable = static_cast<float>(impl_->options.confidence_stable);
  std::vector<Surfel> out;
  for (const SurfelMap::Cell& cell : impl_->map.cells()) {
    for (const Surfel& s : cell.surfels) {
      if (s.confidence >= stable) out.push_back(s);
    }
  }
  return out;
}

std::vector<Surfel> SurfelFusion::allSurfels() const {
  std::vector<Surfel> out;
  out.reserve(impl_->map.size());
  for (const SurfelMap::Cell& cell : impl_->map.cells()) {
    out.insert(out.end(), cell.surfels.begin(), cell.surfels.end());
  }
  return out;
}

std::size_t SurfelFusion::numSurfels() const { return impl_->map.size(); }

const FusionTotals& SurfelFusion::totals() const { return impl_->totals; }

std::size_t SurfelFusion::modelBytes() const { return impl_->map.heapBytes(); }

const TimingStats& SurfelFusion::timing() const { return impl_->timing; }

}  // namespace ltlo::recon
