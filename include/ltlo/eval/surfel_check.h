#pragma once
/// Checks a surfel reconstruction against ground truth (evaluation only; nothing here feeds the
/// reconstruction):
///   - accuracy: the share of surfel area (pi r^2) within `threshold_m` of the static geometry
///     (the simulator's scene.ply, or any triangle mesh of the static scene);
///   - moving objects: the share of surfel area off the static geometry that lies within
///     `threshold_m` of a surface the ground-truth masks call dynamic (masks/ pixels back-projected
///     with their depth and the ground-truth pose, thinned to the centres of 1 cm voxels);
///   - completeness: the share of the static surface seen in the sequence that surfels cover.
///     "Seen": points sampled on the mesh every `sample_spacing_m` that, in at least one checked
///     frame (every `frame_step`-th, ground-truth pose), project into the image where the depth
///     image holds a reading within max(threshold_m, 3 sigma) of the point's depth (so it is not
///     occluded) and the ground-truth mask says static, at a viewing angle (ray to surface
///     normal) of at most `max_view_angle_deg` in one of those frames: a surface only ever seen
///     edge-on has not been measured in any useful sense (its pixels smear along the surface; real
///     sensors mostly return no depth there). "Covered": a surfel disc within `threshold_m` of
///     the point (distance to the disc: along its normal, and beyond its rim in its plane). Also
///     reported: with surfel centres within `threshold_m` (stricter where discs are large), and
///     over the samples seen at any angle.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "ltlo/io/sequence_reader.h"

namespace ltlo::eval {

/// Triangle mesh, world frame, metres.
struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<std::array<int, 3>> triangles;
};

/// Reads a PLY mesh (ascii or binary_little_endian; vertex x, y, z of any numeric type; faces as
/// index lists, polygons split into fans). Throws InputError naming the file and the problem.
TriangleMesh readPlyMesh(const std::string& path);

/// Distances from points to a mesh, exact below `max_distance_m` (a uniform grid of triangle
/// lists). Thread-safe after construction.
class MeshProximity {
 public:
  MeshProximity(const TriangleMesh& mesh, float max_distance_m);
  /// Distance from p to the nearest triangle when below max_distance_m, otherwise +infinity.
  float distance(const Eigen::Vector3f& p) const;

 private:
  const TriangleMesh& mesh_;
  float max_distance_m_;
  float cell_m_;
  Eigen::Vector3f origin_;
  Eigen::Vector3i dims_;
  std::vector<int> cell_start_;  // CSR: triangles of cell c are entries [start[c], start[c+1])
  std::vector<int> cell_triangles_;
};

struct SurfelCheckOptions {
  float threshold_m = 0.03f;         ///< distance that counts as "on" a surface
  int frame_step = 5;                ///< frames checked for visibility and dynamic surfaces
  int pixel_step = 2;                ///< pixel subsampling of the dynamic masks
  float sample_spacing_m = 0.02f;    ///< completeness samples on the mesh
  double depth_noise_m = 0.0025;     ///< sigma(z) = this z^2 in the visibility test
  double max_view_angle_deg = 80.0;  ///< "seen" needs one view at most this oblique
};

struct SurfelCheckResult {
  long num_surfels = 0;
  double total_area_m2 = 0.0;
  double static_area_fraction = 0.0;      ///< accuracy: within threshold of the static geometry
  double dynamic_area_fraction = 0.0;     ///< off static, within threshold of ground-truth dynamic
  double other_area_fraction = 0.0;       ///< neither (outliers, unmodelled geometry)
  double median_static_distance_m = 0.0;  ///< over surfels within the threshold
  long num_samples = 0;                   ///< points sampled on the mesh
  long seen_samples = 0;                  ///< of those, seen in the sequence
  long covered_samples = 0;               ///< seen and covered by a disc
  double completeness = 0.0;              ///< covered / seen
  double completeness_centres = 0.0;    ///< seen samples with a surfel centre within the threshold
  long seen_samples_any_angle = 0;      ///< seen at any viewing angle
  double completeness_any_angle = 0.0;  ///< covered share of those
  int frames_checked = 0;
};

/// Surfel discs in the ground-truth world frame.
struct SurfelDiscs {
  std::vector<Eigen::Vector3f> positions_gt;
  std::vector<Eigen::Vector3f> normals_gt;  ///< unit
  std::vector<float> radii_m;
};

/// `sequence` must have ground truth and masks/ (the reader's default mask source) for the
/// completeness and dynamic figures; when it is null or has no ground truth only the accuracy
/// is computed.
SurfelCheckResult checkSurfels(const SurfelDiscs& discs, const TriangleMesh& scene,
                               const io::SequenceReader* sequence,
                               const SurfelCheckOptions& options);

}  // namespace ltlo::eval
