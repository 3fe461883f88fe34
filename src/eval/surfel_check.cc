#include "ltlo/eval/surfel_check.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include <opencv2/imgproc.hpp>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "ltlo/core/undistorter.h"
#include "ltlo/io/associate.h"

namespace ltlo::eval {
namespace {

// Closest point on triangle (a, b, c) to p, by the Voronoi region of p (vertex, edge or face).
Eigen::Vector3f closestOnTriangle(const Eigen::Vector3f& p, const Eigen::Vector3f& a,
                                  const Eigen::Vector3f& b, const Eigen::Vector3f& c) {
  const Eigen::Vector3f ab = b - a, ac = c - a, ap = p - a;
  const float d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0f && d2 <= 0.0f) return a;
  const Eigen::Vector3f bp = p - b;
  const float d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0f && d4 <= d3) return b;
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0f && d1 >= 0.0f && d3 <= 0.0f) return a + (d1 / (d1 - d3)) * ab;
  const Eigen::Vector3f cp = p - c;
  const float d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0f && d5 <= d6) return c;
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0f && d2 >= 0.0f && d6 <= 0.0f) return a + (d2 / (d2 - d6)) * ac;
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0.0f && (d4 - d3) >= 0.0f && (d5 - d6) >= 0.0f) {
    return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  }
  const float denom = 1.0f / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

uint64_t cellKey(const Eigen::Vector3i& c) {
  const uint64_t mask = (uint64_t{1} << 21) - 1;
  return (static_cast<uint64_t>(c.x()) & mask) | ((static_cast<uint64_t>(c.y()) & mask) << 21) |
         ((static_cast<uint64_t>(c.z()) & mask) << 42);
}

Eigen::Vector3i cellOf(const Eigen::Vector3f& p, float cell_m) {
  return (p / cell_m).array().floor().cast<int>();
}

// Points in cells of `reach_m` (sorted by cell key): visits every point within reach_m of a query.
class PointGrid {
 public:
  PointGrid(const std::vector<Eigen::Vector3f>& points, float reach_m) : reach_m_(reach_m) {
    entries_.reserve(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      entries_.push_back({cellKey(cellOf(points[i], reach_m)), static_cast<int>(i), points[i]});
    }
    std::sort(entries_.begin(), entries_.end(),
              [](const Entry& a, const Entry& b) { return a.key < b.key; });
  }
  /// True when `accept(index, point)` holds for a point within reach_m of p.
  template <typename Accept>
  bool any(const Eigen::Vector3f& p, Accept&& accept) const {
    const Eigen::Vector3i c = cellOf(p, reach_m_);
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const uint64_t key = cellKey(c + Eigen::Vector3i(dx, dy, dz));
          auto it = std::lower_bound(entries_.begin(), entries_.end(), key,
                                     [](const Entry& e, uint64_t k) { return e.key < k; });
          for (; it != entries_.end() && it->key == key; ++it) {
            if ((it->point - p).squaredNorm() <= reach_m_ * reach_m_ &&
                accept(it->index, it->point)) {
              return true;
            }
          }
        }
      }
    }
    return false;
  }
  bool anyWithin(const Eigen::Vector3f& p) const {
    return any(p, [](int, const Eigen::Vector3f&) { return true; });
  }

 private:
  struct Entry {
    uint64_t key;
    int index;
    Eigen::Vector3f point;
  };
  float reach_m_;
  std::vector<Entry> entries_;
};

// Distance from p to the disc (centre c, unit normal n, radius r).
float discDistance(const Eigen::Vector3f& p, const Eigen::Vector3f& c, const Eigen::Vector3f& n,
                   float r) {
  const Eigen::Vector3f d = p - c;
  const float along = n.dot(d);
  const float beyond_rim = std::max(0.0f, (d - along * n).norm() - r);
  return std::sqrt(along * along + beyond_rim * beyond_rim);
}

// Dynamic surface points thinned to one per occupied voxel (its centre; up to 0.87 cm off).
class VoxelCentres {
 public:
  explicit VoxelCentres(float voxel_m) : voxel_m_(voxel_m) {}
  void add(const Eigen::Vector3f& p) {
    const Eigen::Vector3i c = cellOf(p, voxel_m_);
    cells_.push_back(c);
    if (cells_.size() >= 4000000) dedupe();  // bounded memory over long sequences
  }
  std::vector<Eigen::Vector3f> centres() {
    dedupe();
    std::vector<Eigen::Vector3f> out;
    out.reserve(cells_.size());
    for (const Eigen::Vector3i& c : cells_) {
      out.push_back((c.cast<float>() + Eigen::Vector3f::Constant(0.5f)) * voxel_m_);
    }
    return out;
  }

 private:
  void dedupe() {
    auto less = [](const Eigen::Vector3i& a, const Eigen::Vector3i& b) {
      return std::tie(a.x(), a.y(), a.z()) < std::tie(b.x(), b.y(), b.z());
    };
    std::sort(cells_.begin(), cells_.end(), less);
    cells_.erase(std::unique(cells_.begin(), cells_.end()), cells_.end());
  }
  float voxel_m_;
  std::vector<Eigen::Vector3i> cells_;
};

// Points sampled on every triangle about `spacing_m` apart (a grid on the triangle's parameter
// square, the half beyond the diagonal dropped): area / spacing^2 samples per triangle.
struct SurfaceSamples {
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> normals;  // unit, either side
};

SurfaceSamples sampleSurface(const TriangleMesh& mesh, float spacing_m) {
  SurfaceSamples samples;
  for (const std::array<int, 3>& t : mesh.triangles) {
    const Eigen::Vector3f& a = mesh.vertices[t[0]];
    const Eigen::Vector3f ab = mesh.vertices[t[1]] - a, ac = mesh.vertices[t[2]] - a;
    const Eigen::Vector3f cross = ab.cross(ac);
    const float area = 0.5f * cross.norm();
    if (!(area > 0.0f)) continue;
    const int k = std::max(1, static_cast<int>(std::ceil(std::sqrt(2.0f * area) / spacing_m)));
    for (int i = 0; i < k; ++i) {
      for (int j = 0; j < k; ++j) {
        const float u = (i + 0.5f) / k, v = (j + 0.5f) / k;
        if (u + v > 1.0f) continue;
        samples.points.push_back(a + u * ab + v * ac);
        samples.normals.push_back(cross.normalized());
      }
    }
  }
  return samples;
}

}  // namespace

MeshProximity::MeshProximity(const TriangleMesh& mesh, float max_distance_m)
    : mesh_(mesh), max_distance_m_(max_distance_m) {
  LTLO_ASSERT(!mesh.vertices.empty() && max_distance_m > 0.0f, "empty mesh or bad distance");
  Eigen::Vector3f lo = mesh.vertices[0], hi = mesh.vertices[0];
  for (const Eigen::Vector3f& v : mesh.vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  origin_ = lo - Eigen::Vector3f::Constant(max_distance_m);
  const Eigen::Vector3f extent = hi - lo + Eigen::Vector3f::Constant(2.0f * max_distance_m);
  // 10 cm cells, coarser when that would exceed 8 M cells.
  cell_m_ = std::max(0.1f, std::cbrt(extent.prod() / 8e6f));
  dims_ = (extent / cell_m_).array().ceil().cast<int>().cwiseMax(1);
  const std::size_t num_cells = static_cast<std::size_t>(dims_.x()) * dims_.y() * dims_.z();
  std::vector<int> counts(num_cells + 1, 0);
  auto for_each_cell = [&](const std::array<int, 3>& t, auto&& visit) {
    Eigen::Vector3f tlo = mesh.vertices[t[0]], thi = tlo;
    for (int v : t) {
      tlo = tlo.cwiseMin(mesh.vertices[v]);
      thi = thi.cwiseMax(mesh.vertices[v]);
    }
    const Eigen::Vector3i lo_cell =
        ((tlo - origin_ - Eigen::Vector3f::Constant(max_distance_m)) / cell_m_)
            .array()
            .floor()
            .cast<int>()
            .max(0);
    const Eigen::Vector3i hi_cell =
        ((thi - origin_ + Eigen::Vector3f::Constant(max_distance_m)) / cell_m_)
            .array()
            .floor()
            .cast<int>()
            .min((dims_ - Eigen::Vector3i::Ones()).array());
    for (int z = lo_cell.z(); z <= hi_cell.z(); ++z) {
      for (int y = lo_cell.y(); y <= hi_cell.y(); ++y) {
        for (int x = lo_cell.x(); x <= hi_cell.x(); ++x) {
          visit((static_cast<std::size_t>(z) * dims_.y() + y) * dims_.x() + x);
        }
      }
    }
  };
  for (const std::array<int, 3>& t : mesh.triangles) {
    for_each_cell(t, [&](std::size_t cell) { ++counts[cell + 1]; });
  }
  for (std::size_t c = 0; c < num_cells; ++c) counts[c + 1] += counts[c];
  cell_start_ = counts;
  cell_triangles_.resize(static_cast<std::size_t>(counts[num_cells]));
  std::vector<int> fill(counts.begin(), counts.end() - 1);
  for (int t = 0; t < static_cast<int>(mesh.triangles.size()); ++t) {
    for_each_cell(mesh.triangles[t], [&](std::size_t cell) { cell_triangles_[fill[cell]++] = t; });
  }
}

float MeshProximity::distance(const Eigen::Vector3f& p) const {
  const Eigen::Vector3i c = ((p - origin_) / cell_m_).array().floor().cast<int>();
  const float inf = std::numeric_limits<float>::infinity();
  if ((c.array() < 0).any() || (c.array() >= dims_.array()).any()) return inf;
  const std::size_t cell =
      (static_cast<std::size_t>(c.z()) * dims_.y() + c.y()) * dims_.x() + c.x();
  float best = inf;
  for (int k = cell_start_[cell]; k < cell_start_[cell + 1]; ++k) {
    const std::array<int, 3>& t = mesh_.triangles[cell_triangles_[k]];
    const float d =
        (p - closestOnTriangle(p, mesh_.vertices[t[0]], mesh_.vertices[t[1]], mesh_.vertices[t[2]]))
            .norm();
    best = std::min(best, d);
  }
  return best <= max_distance_m_ ? best : inf;
}

namespace {

// What the ground-truth frames saw of the scene.
struct GroundTruthViews {
  explicit GroundTruthViews(std::size_t num_samples) : best_cos(num_samples, 0.0f), seen(num_samples, 0) {}
  // Per sample: the largest |cos| of the viewing angle over the frames that saw it (0 = unseen).
  std::vector<float> best_cos;
  std::vector<uint8_t> seen;
  VoxelCentres dynamic_voxels{0.01f};
};

// The pinhole of the ideal grid in float, as the projections below use it.
struct FloatPinhole {
  explicit FloatPinhole(const PinholeCamera& camera)
      : fx(static_cast<float>(camera.fx())),
        fy(static_cast<float>(camera.fy())),
        cx(static_cast<float>(camera.cx())),
        cy(static_cast<float>(camera.cy())),
        width(camera.width()),
        height(camera.height()) {}
  float fx, fy, cx, cy;
  int width, height;
};

// A ground-truth camera pose T_w_c in float, both ways.
struct FloatPose {
  explicit FloatPose(const SE3& T_w_c)
      : R_w_c(T_w_c.rotationMatrix().cast<float>()),
        t_w_c(T_w_c.translation().cast<float>()),
        R_c_w(R_w_c.transpose()),
        t_c_w(-(R_c_w * t_w_c)) {}
  Eigen::Matrix3f R_w_c;
  Eigen::Vector3f t_w_c;
  Eigen::Matrix3f R_c_w;
  Eigen::Vector3f t_c_w;
};

// A distorting lens: depth and masks are taken onto the ideal grid, where the pinhole holds.
void toIdealGrid(const Undistorter& undistorter, io::RgbdImuFrame* frame) {
  if (!undistorter.active()) return;
  cv::Mat ideal;
  undistorter.toIdeal(frame->depth_m, &ideal, cv::INTER_NEAREST);
  frame->depth_m = ideal;
  if (!frame->mask.empty()) {
    cv::Mat ideal_mask;
    undistorter.toIdeal(frame->mask, &ideal_mask, cv::INTER_NEAREST);
    frame->mask = ideal_mask;
  }
}

// Marks the mesh samples the frame sees as static surface (depth agrees, mask clear) and keeps
// their best viewing angle.
void observeSamples(const io::RgbdImuFrame& frame, const FloatPose& pose, const FloatPinhole& camera,
                    const SurfaceSamples& samples, const SurfelCheckOptions& options,
                    GroundTruthViews* views) {
  const float t = options.threshold_m;
  const bool has_mask = !frame.mask.empty();
  for (std::size_t s = 0; s < samples.points.size(); ++s) {
    const Eigen::Vector3f p = pose.R_c_w * samples.points[s] + pose.t_c_w;
    if (p.z() < 0.05f) continue;
    const int u = static_cast<int>(std::lround(camera.fx * p.x() / p.z() + camera.cx));
    const int v = static_cast<int>(std::lround(camera.fy * p.y() / p.z() + camera.cy));
    if (u < 0 || v < 0 || u >= camera.width || v >= camera.height) continue;
    const float z = frame.depth_m.at<float>(v, u);
    const float tolerance =
        std::max(t, 3.0f * static_cast<float>(options.depth_noise_m) * p.z() * p.z());
    if (z <= 0.0f || std::abs(z - p.z()) > tolerance) continue;
    if (has_mask && frame.mask.at<uint8_t>(v, u) != 0) continue;
    views->seen[s] = 1;
    const float cos_view = std::abs(samples.normals[s].dot(pose.R_w_c * p.normalized()));
    views->best_cos[s] = std::max(views->best_cos[s], cos_view);
  }
}

// The masked pixels with depth (every pixel_step-th), back-projected into the world.
void addDynamicSurface(const io::RgbdImuFrame& frame, const FloatPose& pose,
                       const FloatPinhole& camera, int pixel_step, VoxelCentres* dynamic_voxels) {
  const float fx = camera.fx, fy = camera.fy, cx = camera.cx, cy = camera.cy;
  for (int v = 0; v < camera.height; v += pixel_step) {
    const uint8_t* mask = frame.mask.ptr<uint8_t>(v);
    const float* depth = frame.depth_m.ptr<float>(v);
    for (int u = 0; u < camera.width; u += pixel_step) {
      if (mask[u] == 0 || depth[u] <= 0.0f) continue;
      const float z = depth[u];
      dynamic_voxels->add(pose.R_w_c * Eigen::Vector3f((u - cx) / fx * z, (v - cy) / fy * z, z) +
                          pose.t_w_c);
    }
  }
}

// Ground-truth frames (every frame_step-th with a pose): visibility of mesh samples and dynamic
// surfaces. Returns the number of frames checked.
int observeGroundTruthFrames(const io::SequenceReader& sequence, const SurfaceSamples& samples,
                             const SurfelCheckOptions& options, GroundTruthViews* views) {
  std::vector<double> frame_times_s, gt_times_s;
  for (int i = 0; i < sequence.frameCount(); i += options.frame_step) {
    frame_times_s.push_back(sequence.frameTime(i));
  }
  for (const io::StampedPose& pose : sequence.groundTruth()) gt_times_s.push_back(pose.t_s);
  const FloatPinhole camera(sequence.calib().camera.camera);
  const Undistorter undistorter(sequence.calib().camera.model());
  int frames_checked = 0;
  for (const auto& [a, b] : io::associateTimestamps(frame_times_s, gt_times_s, 1e-3)) {
    io::RgbdImuFrame frame = sequence.load(a * options.frame_step);
    toIdealGrid(undistorter, &frame);
    const FloatPose pose(sequence.groundTruth()[b].T_w_x);
    observeSamples(frame, pose, camera, samples, options, views);
    if (!frame.mask.empty()) addDynamicSurface(frame, pose, camera, options.pixel_step, &views->dynamic_voxels);
    ++frames_checked;
  }
  return frames_checked;
}

// Area shares: static (within t of the mesh), on a dynamic surface, neither.
void computeAreaShares(const SurfelDiscs& discs, const std::vector<float>& distance,
                       const PointGrid& dynamic_points, float t, SurfelCheckResult* result) {
  const std::vector<Eigen::Vector3f>& positions_gt = discs.positions_gt;
  double static_area = 0.0, dynamic_area = 0.0, other_area = 0.0;
  std::vector<double> static_distances;
  for (std::size_t i = 0; i < positions_gt.size(); ++i) {
    const double area = M_PI * discs.radii_m[i] * discs.radii_m[i];
    result->total_area_m2 += area;
    if (distance[i] <= t) {
      static_area += area;
      static_distances.push_back(distance[i]);
    } else if (dynamic_points.anyWithin(positions_gt[i])) {
      dynamic_area += area;
    } else {
      other_area += area;
    }
  }
  if (result->total_area_m2 > 0.0) {
    result->static_area_fraction = static_area / result->total_area_m2;
    result->dynamic_area_fraction = dynamic_area / result->total_area_m2;
    result->other_area_fraction = other_area / result->total_area_m2;
  }
  if (!static_distances.empty()) {
    std::nth_element(static_distances.begin(),
                     static_distances.begin() + static_distances.size() / 2,
                     static_distances.end());
    result->median_static_distance_m = static_distances[static_distances.size() / 2];
  }
}

// Completeness over samples seen at a usable angle; also over every seen sample.
void computeCompleteness(const SurfelDiscs& discs, const SurfaceSamples& samples,
                         const GroundTruthViews& views, const SurfelCheckOptions& options,
                         SurfelCheckResult* result) {
  const std::vector<Eigen::Vector3f>& positions_gt = discs.positions_gt;
  const float t = options.threshold_m;
  const PointGrid surfel_centres(positions_gt, t);
  float max_radius_m = 0.0f;
  for (float r : discs.radii_m) max_radius_m = std::max(max_radius_m, r);
  const PointGrid surfel_discs(positions_gt, t + max_radius_m);
  const float min_cos = static_cast<float>(std::cos(options.max_view_angle_deg * M_PI / 180.0));
  long covered_by_centres = 0, seen_any_angle = 0, covered_any_angle = 0;
  for (std::size_t s = 0; s < samples.points.size(); ++s) {
    if (!views.seen[s]) continue;
    const Eigen::Vector3f& q = samples.points[s];
    const bool covered = surfel_discs.any(q, [&](int i, const Eigen::Vector3f& c) {
      return discDistance(q, c, discs.normals_gt[i], discs.radii_m[i]) <= t;
    });
    ++seen_any_angle;
    if (covered) ++covered_any_angle;
    if (views.best_cos[s] < min_cos) continue;
    ++result->seen_samples;
    if (covered) ++result->covered_samples;
    if (surfel_centres.anyWithin(q)) ++covered_by_centres;
  }
  if (result->seen_samples > 0) {
    result->completeness = static_cast<double>(result->covered_samples) / result->seen_samples;
    result->completeness_centres = static_cast<double>(covered_by_centres) / result->seen_samples;
  }
  result->seen_samples_any_angle = seen_any_angle;
  if (seen_any_angle > 0) {
    result->completeness_any_angle = static_cast<double>(covered_any_angle) / seen_any_angle;
  }
}

}  // namespace

SurfelCheckResult checkSurfels(const SurfelDiscs& discs, const TriangleMesh& scene,
                               const io::SequenceReader* sequence,
                               const SurfelCheckOptions& options) {
  const std::vector<Eigen::Vector3f>& positions_gt = discs.positions_gt;
  LTLO_ASSERT(
      discs.normals_gt.size() == positions_gt.size() && discs.radii_m.size() == positions_gt.size(),
      "surfel positions, normals and radii differ in size");
  const float t = options.threshold_m;
  SurfelCheckResult result;
  result.num_surfels = static_cast<long>(positions_gt.size());
  const MeshProximity proximity(scene, t);

  // Static distance of every surfel.
  std::vector<float> distance(positions_gt.size());
  for (std::size_t i = 0; i < positions_gt.size(); ++i)
    distance[i] = proximity.distance(positions_gt[i]);

  const SurfaceSamples samples = sampleSurface(scene, options.sample_spacing_m);
  result.num_samples = static_cast<long>(samples.points.size());
  GroundTruthViews views(samples.points.size());
  if (sequence != nullptr && sequence->hasGroundTruth()) {
    result.frames_checked = observeGroundTruthFrames(*sequence, samples, options, &views);
  } else if (sequence != nullptr) {
    log::warn(sequence->directory(),
              ": no ground truth; completeness and moving-object area not computed");
  }
  const PointGrid dynamic_points(views.dynamic_voxels.centres(), t);
  computeAreaShares(discs, distance, dynamic_points, t, &result);
  if (result.frames_checked > 0) computeCompleteness(discs, samples, views, options, &result);
  return result;
}

}  // namespace ltlo::eval
