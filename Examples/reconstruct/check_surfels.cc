// check_surfels: a surfel reconstruction against the sequence's ground truth (evaluation only).
//
//   check_surfels --surfels PLY --sequence SEQ [--trajectory FILE] [--scene PLY] [--threshold M]
//                 [--frame-step N] [--json FILE]
//
// The surfels live in the world frame of the trajectory they were fused with (--trajectory, e.g.
// RUN/trajectory.txt); it is aligned to SEQ/groundtruth.txt (SE3 Umeyama over matched poses) to
// bring the surfels into the ground-truth frame; without --trajectory they are taken to be in that
// frame already. Static geometry: SEQ/scene.ply (or --scene). Prints "name value" lines:
//   accuracy                 share of surfel area within the threshold of the static geometry
//   dynamic_area_fraction    share on surfaces the ground-truth masks call dynamic (moving boxes)
//   other_area_fraction      neither
//   completeness             share of the static surface seen in the sequence that surfels cover
//                            at <= 80 deg once (a disc within the threshold; completeness_centres:
//                            a centre within; completeness_any_angle: seen at any angle)
// Exit status: 0 done, 2 bad input (naming the file).
#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/eval/surfel_check.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/io/metrics_json.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/io/trajectory_io.h"
#include "ltlo/recon/surfel_ply.h"

namespace {

using namespace ltlo;
namespace fs = std::filesystem;

struct Arguments {
  std::string surfels_path;
  std::string sequence_dir;
  std::string trajectory_path;
  std::string scene_path;
  std::string json_path;
  double threshold_m = 0.03;
  int frame_step = 5;
  double max_view_angle_deg = 80.0;
};

int run(const Arguments& args) {
  const std::vector<recon::Surfel> surfels = recon::readSurfelPly(args.surfels_path);
  io::SequenceReaderOptions reader_options;
  reader_options.read_masks = true;  // evaluation: the ground-truth masks say which surfaces move
  const io::SequenceReader sequence = io::SequenceReader::open(args.sequence_dir, reader_options);
  const std::string scene_path = args.scene_path.empty()
                                     ? (fs::path(args.sequence_dir) / "scene.ply").string()
                                     : args.scene_path;
  const eval::TriangleMesh scene = eval::readPlyMesh(scene_path);

  Sim3 S_gt_est;
  double alignment_ate_m = 0.0;
  if (!args.trajectory_path.empty()) {
    if (!sequence.hasGroundTruth()) {
      throw InputError(args.sequence_dir, 0, "no groundtruth.txt to align the trajectory with");
    }
    const io::Trajectory est = io::readTumTrajectory(args.trajectory_path);
    const eval::MatchedTrajectories matched =
        eval::associateTrajectories(sequence.groundTruth(), est);
    if (matched.gt.size() < 3) {
      throw InputError(args.trajectory_path, 0, "fewer than 3 poses match the ground truth");
    }
    const eval::AteResult ate = eval::computeAte(matched, /*with_scale=*/false);
    S_gt_est = ate.S_gt_est;
    alignment_ate_m = ate.error_m.rmse;
  }
  eval::SurfelDiscs discs;
  const Eigen::Matrix3f R_gt_est = S_gt_est.rotationMatrix().cast<float>();
  for (const recon::Surfel& s : surfels) {
    discs.positions_gt.push_back((S_gt_est * s.position_w.cast<double>()).cast<float>());
    discs.normals_gt.push_back(R_gt_est * s.normal_w);
    discs.radii_m.push_back(s.radius_m);
  }
  eval::SurfelCheckOptions options;
  options.threshold_m = static_cast<float>(args.threshold_m);
  options.frame_step = args.frame_step;
  options.max_view_angle_deg = args.max_view_angle_deg;
  const eval::SurfelCheckResult r = eval::checkSurfels(discs, scene, &sequence, options);

  io::Metrics metrics;
  metrics.set("surfels", static_cast<int64_t>(r.num_surfels));
  metrics.set("surfel_area_m2", r.total_area_m2);
  metrics.set("accuracy", r.static_area_fraction);
  metrics.set("dynamic_area_fraction", r.dynamic_area_fraction);
  metrics.set("other_area_fraction", r.other_area_fraction);
  metrics.set("median_static_distance_m", r.median_static_distance_m);
  metrics.set("completeness", r.completeness);
  metrics.set("completeness_centres", r.completeness_centres);
  metrics.set("completeness_any_angle", r.completeness_any_angle);
  metrics.set("seen_samples", static_cast<int64_t>(r.seen_samples));
  metrics.set("seen_samples_any_angle", static_cast<int64_t>(r.seen_samples_any_angle));
  metrics.set("covered_samples", static_cast<int64_t>(r.covered_samples));
  metrics.set("mesh_samples", static_cast<int64_t>(r.num_samples));
  metrics.set("frames_checked", r.frames_checked);
  metrics.set("threshold_m", args.threshold_m);
  metrics.set("alignment_ate_rmse_m", alignment_ate_m);
  std::cout << metrics.toText();
  if (!args.json_path.empty()) metrics.writeJson(args.json_path);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  log::initFromEnvironment();
  CLI::App app{"Surfel reconstruction against ground truth: accuracy, completeness, moving boxes"};
  Arguments args;
  app.add_option("--surfels", args.surfels_path, "surfels.ply written by reconstruct")->required();
  app.add_option("--sequence", args.sequence_dir,
                 "the sequence (groundtruth.txt, masks/, scene.ply)")
      ->required();
  app.add_option("--trajectory", args.trajectory_path,
                 "trajectory the surfels were fused with (aligned to the ground truth)");
  app.add_option("--scene", args.scene_path, "static geometry PLY (default SEQ/scene.ply)");
  app.add_option("--threshold", args.threshold_m, "distance counted as on a surface (m)")
      ->check(CLI::PositiveNumber);
  app.add_option("--frame-step", args.frame_step, "check every n-th frame for visibility")
      ->check(CLI::PositiveNumber);
  app.add_option("--max-view-angle", args.max_view_angle_deg,
                 "a surface counts as seen when viewed at most this obliquely once (deg)")
      ->check(CLI::Range(1.0, 90.0));
  app.add_option("--json", args.json_path, "also write the figures to this JSON file");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "check_surfels: " << e.what() << "\n" << app.help();
    return 2;
  }
  try {
    return run(args);
  } catch (const InputError& e) {
    std::cerr << "check_surfels: " << e.what() << "\n";
    return 2;
  } catch (const ConfigError& e) {
    std::cerr << "check_surfels: " << e.what() << "\n";
    return 2;
  }
}
