#include "ltlo/recon/surfel_fusion.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "ltlo/core/assert.h"
#include "ltlo/core/timing.h"
#include "measurement.h"
#include "surfel_map.h"

namespace ltlo::recon {
namespace {

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
  Measurement measurement;
  std::vector<float> index_depth_m;
  std::vector<int32_t> index_id;
  std::vector<Surfel*> rendered;
  std::vector<int> visible_cells;
  std::vector<Surfel> created;

  void renderIndexMap(const Eigen::Matrix3f& R_c_w, const Eigen::Vector3f& t_c_w);
  void associateAndFuse(const Eigen::Matrix3f& R_w_c, const Eigen::Vector3f& t_w_c, float t_rel_s,
                        FusionFrameStats* stats);
  void removeFreeSpaceViolations(const Eigen::Matrix3f& R_c_w, const Eigen::Vector3f& t_c_w,
                                 float t_rel_s, FusionFrameStats* stats);
  void cleanVisibleCells(float t_rel_s, FusionFrameStats* stats);
};

SurfelFusion::SurfelFusion(const PinholeCamera& camera, const ReconOptions& options)
    : impl_(std::make_unique<Impl>()) {
  options.validate();
  Impl& im = *impl_;
  im.camera = camera;
  im.options = options;
  im.fusion_camera = fusionCamera(camera, options.downsample);
  LTLO_ASSERT(im.fusion_camera.width() >= 3 && im.fusion_camera.height() >= 3,
              "fusion grid " << im.fusion_camera.width() << "x" << im.fusion_camera.height());
  im.index_camera = indexCamera(im.fusion_camera);
  im.planes = frustumPlanes(im.fusion_camera);
  im.cos_assoc_angle = static_cast<float>(std::cos(options.assoc_max_angle_deg * M_PI / 180.0));
}

SurfelFusion::~SurfelFusion() = default;

void SurfelFusion::Impl::renderIndexMap(const Eigen::Matrix3f& R_c_w,
                                        const Eigen::Vector3f& t_c_w) {
  const int width = index_camera.width();
  const int height = index_camera.height();
  index_depth_m.assign(static_cast<std::size_t>(width) * height,
                       std::numeric_limits<float>::infinity());
  index_id.assign(index_depth_m.size(), -1);
  rendered.clear();
  visible_cells.clear();

  // Surfels farther than the farthest measurement plus its window can neither take a measurement
  // nor be seen through.
  const float z_near = 0.5f * static_cast<float>(options.min_depth_m);
  const float z_far = static_cast<float>(options.max_depth_m) +
                      associationWindowM(options, static_cast<float>(options.max_depth_m));
  const float cell_radius = 0.5f * std::sqrt(3.0f) * map.cellSizeM() + kCellMarginM;
  std::vector<SurfelMap::Cell>& cells = map.cells();
  for (int c = 0; c < static_cast<int>(cells.size()); ++c) {
    const Eigen::Vector3f centre_c = transform(R_c_w, cells[c].centre_w, t_c_w);
    if (centre_c.z() + cell_radius < z_near || centre_c.z() - cell_radius > z_far) continue;
    bool inside = true;
    for (const Eigen::Vector3f& n : planes) inside = inside && n.dot(centre_c) >= -cell_radius;
    if (inside) visible_cells.push_back(c);
  }

  const float fx = static_cast<float>(index_camera.fx()),
              fy = static_cast<float>(index_camera.fy());
  const float cx = static_cast<float>(index_camera.cx()),
              cy = static_cast<float>(index_camera.cy());
  for (int c : visible_cells) {
    for (Surfel& s : cells[c].surfels) {
      const Eigen::Vector3f p = transform(R_c_w, s.position_w, t_c_w);
      if (p.z() < z_near || p.z() > z_far) continue;
      if (rotate(R_c_w, s.normal_w).dot(p) > 0.0f) continue;  // seen from behind
      const float inv_z = 1.0f / p.z();
      const int u = static_cast<int>(std::floor(fx * p.x() * inv_z + cx + 0.5f));
      const int v = static_cast<int>(std::floor(fy * p.y() * inv_z + cy + 0.5f));
      if (u < 0 || v < 0 || u >= width || v >= height) continue;
      const std::size_t k = static_cast<std::size_t>(v) * width + u;
      if (p.z() >= index_depth_m[k]) continue;
      index_depth_m[k] = p.z();
      index_id[k] = static_cast<int32_t>(rendered.size());
      rendered.push_back(&s);
    }
  }
}

void SurfelFusion::Impl::associateAndFuse(const Eigen::Matrix3f& R_w_c,
                                          const Eigen::Vector3f& t_w_c, float t_rel_s,
                                          FusionFrameStats* stats) {
  const Measurement& m = measurement;
  const int index_width = index_camera.width();
  created.clear();
  for (int j = 0; j < m.height; ++j) {
    for (int i = 0; i < m.width; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * m.width + i;
      if (m.state[k] != PixelState::kFusable) continue;
      const Eigen::Vector3f p_w = transform(R_w_c, m.point_c[k], t_w_c);
      const Eigen::Vector3f n_w = rotate(R_w_c, m.normal_c[k]);
      const float window = associationWindowM(options, m.point_c[k].z());
      // The 2 x 2 index pixels of this fusion pixel: the most confident compatible surfel.
      Surfel* best = nullptr;
      for (int dv = 0; dv < 2; ++dv) {
        const int32_t* ids = &index_id[static_cast<std::size_t>(2 * j + dv) * index_width + 2 * i];
        for (int du = 0; du < 2; ++du) {
          if (ids[du] < 0) continue;
          Surfel* s = rendered[ids[du]];
          if (std::abs(s->normal_w.dot(p_w - s->position_w)) > window) continue;
          if (s->normal_w.dot(n_w) < cos_assoc_angle) continue;
          if (best == nullptr || s->confidence > best->confidence) best = s;
        }
      }
      const float alpha = m.alpha[k];
      const float radius = m.radius_m[k];
      if (best == nullptr) {
        // No surfel centre in this pixel: does a disc centred in the ring of index pixels around
        // it cover the point? (Projected surfel centres shift by sub-pixel amounts between views,
        // which leaves some blocks empty and others with two; without this test every empty block
        // would add a surfel on top of a disc. A disc's radius is about 1.4 index pixels at the
        // distance it was made from, so one ring of index pixels suffices.)
        bool covered = false;
        for (int v = std::max(0, 2 * j - 1); v < std::min(index_camera.height(), 2 * j + 3); ++v) {
          for (int u = std::max(0, 2 * i - 1); u < std::min(index_width, 2 * i + 3); ++u) {
            const int32_t id = index_id[static_cast<std::size_t>(v) * index_width + u];
            if (id < 0) continue;
            Surfel* s = rendered[id];
            const Eigen::Vector3f d = p_w - s->position_w;
            const float along = s->normal_w.dot(d);
            if (std::abs(along) > window || s->normal_w.dot(n_w) < cos_assoc_angle) continue;
            if ((d - along * s->normal_w).squaredNorm() > s->radius_m * s->radius_m) continue;
            covered = true;
            if (s->last_seen_s != t_rel_s &&
                (best == nullptr || s->confidence > best->confidence)) {
              best = s;
            }
          }
        }
        if (covered && best == nullptr) {  // its surfel took a measurement this frame already
          ++stats->covered;
          continue;
        }
      }
      if (best != nullptr) {
        Surfel& s = *best;
        if (radius <= kCoarserRadiusRatio * s.radius_m) {
          // Keller et al. 2013, Eq. 4: confidence-weighted running averages.
          const float w_old = s.confidence / (s.confidence + alpha);
          const float w_new = 1.0f - w_old;
          s.position_w = w_old * s.position_w + w_new * p_w;
          s.normal_w = (w_old * s.normal_w + w_new * n_w).normalized();
          s.colour_rgb = w_old * s.colour_rgb + w_new * m.colour_rgb[k];
          s.radius_m = w_old * s.radius_m + w_new * radius;
        }
        s.confidence += alpha;
        s.last_seen_s = t_rel_s;
        if (s.violations > 0) --s.violations;
        ++stats->merged;
      } else {
        Surfel s;
        s.position_w = p_w;
        s.normal_w = n_w;
        s.radius_m = radius;
        s.confidence = alpha;
        s.colour_rgb = m.colour_rgb[k];
        s.first_seen_s = t_rel_s;
        s.last_seen_s = t_rel_s;
        created.push_back(s);
      }
    }
  }
  stats->created = static_cast<int>(created.size());
}

void SurfelFusion::Impl::removeFreeSpaceViolations(const Eigen::Matrix3f& R_c_w,
                                                   const Eigen::Vector3f& t_c_w, float t_rel_s,
                                                   FusionFrameStats* stats) {
  if (options.free_space_votes == 0) return;
  const Measurement& m = measurement;
  const float stable = static_cast<float>(options.confidence_stable);
  const int index_width = index_camera.width();
  const int index_height = index_camera.height();
  for (int v = 0; v < index_height; ++v) {
    for (int u = 0; u < index_width; ++u) {
      const int32_t id = index_id[static_cast<std::size_t>(v) * index_width + u];
      if (id < 0) continue;
      const std::size_t k = static_cast<std::size_t>(v / 2) * m.width + u / 2;
      if (m.state[k] == PixelState::kInvalid) continue;
      Surfel& s = *rendered[id];
      if (s.confidence < 0.0f || s.last_seen_s == t_rel_s) continue;  // removed, or just fused
      // Violation: the surfel lies in front of the measured surface, beyond the association
      // window along the measured normal and along the ray, so the sensor saw through it.
      const Eigen::Vector3f& p_m = m.point_c[k];
      const float window = associationWindowM(options, p_m.z());
      const Eigen::Vector3f p_s = transform(R_c_w, s.position_w, t_c_w);
      if (m.normal_c[k].dot(p_s - p_m) <= window || p_s.z() >= p_m.z() - window) continue;
      if (s.confidence >= stable && ++s.violations < options.free_space_votes) continue;
      s.confidence = -1.0f;
      ++stats->removed_free_space;
    }
  }
}

void SurfelFusion::Impl::cleanVisibleCells(float t_rel_s, FusionFrameStats* stats) {
  const float stable = static_cast<float>(options.confidence_stable);
  const float window_s = static_cast<float>(options.unstable_time_s);
  std::vector<SurfelMap::Cell>& cells = map.cells();
  for (int c : visible_cells) {
    for (Surfel& s : cells[c].surfels) {
      if (s.confidence >= 0.0f && s.confidence < stable && t_rel_s - s.first_seen_s > window_s) {
        s.confidence = -1.0f;
        ++stats->removed_unstable;
      }
    }
    SurfelMap::compact(&cells[c]);
  }
}

FusionFrameStats SurfelFusion::integrate(const FusionFrame& frame) {
  Impl& im = *impl_;
  if (!im.started) {
    im.started = true;
    im.t0_s = frame.t_s;
  }
  const float t_rel_s = static_cast<float>(frame.t_s - im.t0_s);
  FusionFrameStats stats;
  ScopedTimer measurement_timer(im.timing, "recon.measurement");
  computeMeasurement(frame, im.camera, im.fusion_camera, im.options, &im.measurement);
  measurement_timer.stop();
  stats.measured_pixels = im.measurement.num_geometry;
  stats.fused_pixels = im.measurement.num_fusable;

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
    im.associateAndFuse(R_w_c, t_w_c, t_rel_s, &stats);
  }
  {
    ScopedTimer timer(im.timing, "recon.free_space");
    im.removeFreeSpaceViolations(R_c_w, t_c_w, t_rel_s, &stats);
  }
  {
    ScopedTimer timer(im.timing, "recon.clean_insert");
    im.cleanVisibleCells(t_rel_s, &stats);
    for (const Surfel& s : im.created) im.map.insert(s);
  }

  ++im.totals.frames;
  im.totals.merged += stats.merged;
  im.totals.created += stats.created;
  im.totals.removed_unstable += stats.removed_unstable;
  im.totals.removed_free_space += stats.removed_free_space;
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
