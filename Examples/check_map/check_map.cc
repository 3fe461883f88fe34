// check_map: map hygiene of a run -- the share of its static map points that lie on moving objects.
//
//   check_map --run DIR --sequence DIR [--threshold M] [--min-beta B] [--max-share S]
//             [--frame-step N] [--list FILE]
//
// The sequence's scene.ply is the static geometry of the simulated room (world frame); boxes and
// carried objects are not in it. The run's static_map.ply (world frame of its active map) is
// brought into the sequence's frame by the rigid alignment (Umeyama) of the active map's
// keyframe camera centres (keyframes.txt) with the ground truth at the same times. A map point
// farther than --threshold (default 0.10 m) from every static triangle is off the static geometry.
// Points at depth edges can be mapped that far from any surface too (foreground texture with
// background depth), so the masks confirm: in every --frame-step-th ground-truth frame, a point
// that projects where the ground-truth depth image sees a surface at its own depth (within
// 3 cm + 2 %) is "on" that surface, and masks/ says whether that surface was moving. A point off
// the static geometry is on a moving object when it was on moving surfaces more often than on
// static ones; one never on any surface is counted apart (unexplained). Prints `name value`
// lines: map_points, off_static_geometry, on_moving_objects, unexplained, moving_share
// (on_moving_objects / map_points), threshold_m, alignment_rmse_m, keyframes_aligned. Exit 0,
// 1 when moving_share > --max-share (default 0.01), 2 on bad input.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include <CLI/CLI.hpp>
#include <opencv2/imgcodecs.hpp>

#include "ltlo/core/errors.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/system/run_outputs.h"

namespace {

using namespace ltlo;

struct Triangle {
  Vec3 a, b, c;
};

/// Triangles of an ASCII PLY mesh (vertex x y z first, faces as index lists; polygons fanned).
std::vector<Triangle> readSceneTriangles(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open the scene mesh");
  std::string line;
  int line_number = 0, vertices = -1, faces = -1;
  auto next = [&]() {
    if (!std::getline(in, line)) throw InputError(path, line_number, "unexpected end of file");
    ++line_number;
  };
  next();
  if (line != "ply") throw InputError(path, 1, "not a PLY file");
  while (true) {
    next();
    std::istringstream words(line);
    std::string keyword, element;
    words >> keyword;
    if (keyword == "format" && line.find("ascii") == std::string::npos) {
      throw InputError(path, line_number, "expected an ASCII PLY, got '" + line + "'");
    }
    if (keyword == "element") {
      int count = 0;
      words >> element >> count;
      if (element == "vertex") vertices = count;
      if (element == "face") faces = count;
    }
    if (keyword == "end_header") break;
  }
  if (vertices < 0 || faces < 0) throw InputError(path, line_number, "needs vertex and face elements");
  // Nothing is sized by the header's counts before the lines are there: a corrupt count ends in
  // "unexpected end of file", not in a huge allocation.
  std::vector<Vec3> points;
  for (int v = 0; v < vertices; ++v) {
    next();
    std::istringstream words(line);
    Vec3 p;
    if (!(words >> p.x() >> p.y() >> p.z()) || !p.allFinite()) throw InputError(path, line_number, "bad vertex '" + line + "'");
    points.push_back(p);
  }
  std::vector<Triangle> triangles;
  std::vector<int> ids;
  for (int f = 0; f < faces; ++f) {
    next();
    std::istringstream words(line);
    int n = 0;
    if (!(words >> n) || n < 3) throw InputError(path, line_number, "bad face '" + line + "'");
    ids.clear();
    for (int k = 0; k < n; ++k) {
      int id = -1;
      if (!(words >> id) || id < 0 || id >= vertices) throw InputError(path, line_number, "bad face '" + line + "'");
      ids.push_back(id);
    }
    for (int k = 1; k + 1 < n; ++k) {
      triangles.push_back({points[static_cast<std::size_t>(ids[0])], points[static_cast<std::size_t>(ids[static_cast<std::size_t>(k)])],
                           points[static_cast<std::size_t>(ids[static_cast<std::size_t>(k + 1)])]});
    }
  }
  return triangles;
}

/// Distance from p to a triangle (closest point by Voronoi region of the triangle's features).
double pointTriangleDistance(const Vec3& p, const Triangle& t) {
  const Vec3 ab = t.b - t.a, ac = t.c - t.a, ap = p - t.a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return (p - t.a).norm();
  const Vec3 bp = p - t.b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return (p - t.b).norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return (p - (t.a + ab * (d1 / (d1 - d3)))).norm();
  const Vec3 cp = p - t.c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return (p - t.c).norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return (p - (t.a + ac * (d2 / (d2 - d6)))).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    return (p - (t.b + (t.c - t.b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))))).norm();
  }
  const double denominator = 1.0 / (va + vb + vc);
  return (p - (t.a + ab * (vb * denominator) + ac * (vc * denominator))).norm();
}

/// Triangles binned in cubic cells of `cell` m; each triangle is in every cell its bounding box
/// grown by `cell` touches, so all triangles within `cell` of a point are in the point's cell.
class TriangleGrid {
 public:
  TriangleGrid(std::vector<Triangle> triangles, double cell) : triangles_(std::move(triangles)), cell_(cell) {
    for (std::size_t i = 0; i < triangles_.size(); ++i) {
      const Triangle& t = triangles_[i];
      const Vec3 lo = t.a.cwiseMin(t.b).cwiseMin(t.c).array() - cell_;
      const Vec3 hi = t.a.cwiseMax(t.b).cwiseMax(t.c).array() + cell_;
      for (long x = key(lo.x()); x <= key(hi.x()); ++x) {
        for (long y = key(lo.y()); y <= key(hi.y()); ++y) {
          for (long z = key(lo.z()); z <= key(hi.z()); ++z) cells_[pack(x, y, z)].push_back(i);
        }
      }
    }
  }
  bool within(const Vec3& p, double distance) const {
    const auto it = cells_.find(pack(key(p.x()), key(p.y()), key(p.z())));
    if (it == cells_.end()) return false;
    return std::any_of(it->second.begin(), it->second.end(),
                       [&](std::size_t i) { return pointTriangleDistance(p, triangles_[i]) <= distance; });
  }

 private:
  long key(double v) const { return static_cast<long>(std::floor(v / cell_)); }
  static long long pack(long x, long y, long z) {
    return ((static_cast<long long>(x) & 0x1FFFFF) << 42) | ((static_cast<long long>(y) & 0x1FFFFF) << 21) |
           (static_cast<long long>(z) & 0x1FFFFF);
  }
  std::vector<Triangle> triangles_;
  double cell_;
  std::unordered_map<long long, std::vector<std::size_t>> cells_;
};

struct Arguments {
  std::string run_dir, sequence_dir, list_path;
  double threshold_m = 0.10;
  double min_beta = 0.5;
  double max_share = 0.01;
  int frame_step = 5;
};

int run(const Arguments& args) {
  const std::vector<system::MapPointRecord> all_points = system::readStaticMapPly(args.run_dir + "/static_map.ply");
  const std::vector<system::KeyFrameRecord> keyframes = system::readKeyFrames(args.run_dir + "/keyframes.txt");
  io::SequenceReaderOptions reader_options;
  reader_options.read_masks = true;  // evaluation: the ground-truth masks say which surfaces move
  const io::SequenceReader sequence = io::SequenceReader::open(args.sequence_dir, reader_options);
  const io::Trajectory& ground_truth = sequence.groundTruth();
  if (keyframes.empty() || ground_truth.empty()) {
    throw InputError(args.run_dir + "/keyframes.txt", 0, "no keyframes, or the sequence has no ground truth");
  }
  // The active map: the map of the last keyframe in time; its keyframe centres against the truth.
  const std::uint64_t active =
      std::max_element(keyframes.begin(), keyframes.end(), [](const auto& a, const auto& b) { return a.t_s < b.t_s; })->map;
  io::Trajectory estimate;
  for (const system::KeyFrameRecord& kf : keyframes) {
    if (kf.map == active) estimate.push_back({kf.t_s, kf.T_w_c});
  }
  const eval::MatchedTrajectories matched = eval::associateTrajectories(ground_truth, estimate);
  if (matched.gt.size() < 3) throw InputError(args.run_dir + "/keyframes.txt", 0, "fewer than 3 keyframes of the active map have ground truth");
  const eval::AteResult ate = eval::computeAte(matched, false);
  const Sim3& S_gt_est = ate.S_gt_est;

  TriangleGrid grid(readSceneTriangles(args.sequence_dir + "/scene.ply"), args.threshold_m);
  std::vector<Vec3> points_gt;
  std::vector<Vec3> off_geometry;
  for (const system::MapPointRecord& point : all_points) {
    if (point.beta < args.min_beta) continue;
    const Vec3 p = S_gt_est * point.p_w;
    points_gt.push_back(p);
    if (!grid.within(p, args.threshold_m)) off_geometry.push_back(p);
  }

  // Mask confirmation over the ground-truth frames.
  std::vector<int> moving_votes(off_geometry.size(), 0), static_votes(off_geometry.size(), 0);
  const PinholeCamera& camera = sequence.calib().camera.camera;
  const CameraModel lens_camera = sequence.calib().camera.model();  // raw images: through the lens
  const double depth_factor = sequence.calib().camera.depth_map_factor;
  std::size_t gt_index = 0;
  for (int f = 0; f < sequence.frameCount() && !off_geometry.empty(); f += std::max(1, args.frame_step)) {
    const io::FrameFiles& files = sequence.frameFiles(f);
    if (files.mask_path.empty()) continue;
    while (gt_index + 1 < ground_truth.size() && ground_truth[gt_index + 1].t_s <= files.t_s + 1e-6) ++gt_index;
    if (std::abs(ground_truth[gt_index].t_s - files.t_s) > 0.02) continue;
    const cv::Mat mask = cv::imread(files.mask_path, cv::IMREAD_GRAYSCALE);
    const cv::Mat depth = cv::imread(files.depth_path, cv::IMREAD_UNCHANGED);
    if (mask.empty() || depth.empty() || depth.type() != CV_16U) throw InputError(files.depth_path, 0, "cannot read depth or mask");
    const SE3 T_c_w = ground_truth[gt_index].T_w_x.inverse();
    for (std::size_t k = 0; k < off_geometry.size(); ++k) {
      const Vec3 p_c = T_c_w * off_geometry[k];
      if (p_c.z() < 0.1) continue;
      const Vec2 uv = lens_camera.isDistorted() ? lens_camera.project(p_c) : camera.project(p_c);
      const int col = static_cast<int>(std::lround(uv.x())), row = static_cast<int>(std::lround(uv.y()));
      if (col < 0 || row < 0 || col >= depth.cols || row >= depth.rows || col >= mask.cols || row >= mask.rows) continue;
      const double image_depth_m = depth.at<std::uint16_t>(row, col) / depth_factor;
      if (image_depth_m <= 0.0 || std::abs(image_depth_m - p_c.z()) > 0.03 + 0.02 * p_c.z()) continue;
      (mask.at<std::uint8_t>(row, col) > 127 ? moving_votes[k] : static_votes[k])++;
    }
  }
  int on_moving = 0, unexplained = 0;
  std::ofstream list;
  if (!args.list_path.empty()) {
    list.open(args.list_path);
    if (!list) throw InputError(args.list_path, 0, "cannot open for writing");
  }
  for (std::size_t k = 0; k < off_geometry.size(); ++k) {
    if (moving_votes[k] == 0 && static_votes[k] == 0) {
      ++unexplained;
    } else if (moving_votes[k] > static_votes[k]) {
      ++on_moving;
      if (list) list << off_geometry[k].x() << " " << off_geometry[k].y() << " " << off_geometry[k].z() << "\n";
    }
  }
  const double share = points_gt.empty() ? 0.0 : static_cast<double>(on_moving) / static_cast<double>(points_gt.size());
  std::printf("map_points %zu\noff_static_geometry %zu\non_moving_objects %d\nunexplained %d\nmoving_share %.6f\n"
              "threshold_m %.3f\nalignment_rmse_m %.6f\nkeyframes_aligned %zu\n",
              points_gt.size(), off_geometry.size(), on_moving, unexplained, share, args.threshold_m,
              ate.error_m.rmse, matched.gt.size());
  return share > args.max_share ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Share of a run's static map points on moving objects (simulated sequences)"};
  Arguments args;
  app.add_option("--run", args.run_dir, "run output folder (static_map.ply, keyframes.txt)")->required();
  app.add_option("--sequence", args.sequence_dir, "sequence folder (scene.ply, groundtruth.txt, masks/)")->required();
  app.add_option("--threshold", args.threshold_m, "distance to the static geometry, m")->check(CLI::PositiveNumber);
  app.add_option("--min-beta", args.min_beta, "map points counted (the run's static ones)")->check(CLI::Range(0.0, 1.0));
  app.add_option("--max-share", args.max_share, "exit 1 above this share")->check(CLI::Range(0.0, 1.0));
  app.add_option("--frame-step", args.frame_step, "every N-th ground-truth frame confirms")->check(CLI::PositiveNumber);
  app.add_option("--list", args.list_path, "write the points on moving objects (sequence frame) here");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    return run(args);
  } catch (const InputError& e) {
    std::fprintf(stderr, "check_map: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "check_map: error: %s\n", e.what());
    return 2;
  }
}
