// evaluate: ATE / RPE of an estimated trajectory against ground truth, and the static-background
// IoU of predicted masks. Prints one "name value" line per metric and writes the same keys to
// JSON. Bad input exits 2 with a message naming the file, line and value; any other error exits 1.
// Quaternions that are not unit are normalised with one warning per file.
// --world-from GT0 EST0: the estimate is in the world frame of an earlier run (a run started in
// that run's saved atlas, rgbd_inertial --load-atlas), whose trajectory EST0 and ground truth GT0
// are given: the alignment of EST0 to GT0 is applied to --est instead of --est's own best one, so
// "ate_fixed_rmse_m" also counts how well the run placed itself in the earlier world; the usual
// aligned figures are printed beside it.
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/eval/mask_iou.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/io/metrics_json.h"
#include "ltlo/io/trajectory_io.h"

namespace {

constexpr int kBadInput = 2;

bool endsWith(const std::string& text, const std::string& suffix) {
  return text.size() >= suffix.size() &&
         text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// EuRoC CSV for *.csv, TUM text otherwise.
ltlo::io::Trajectory readTrajectory(const std::string& path) {
  ltlo::io::Trajectory trajectory = endsWith(path, ".csv") ? ltlo::io::readEurocTrajectory(path)
                                                           : ltlo::io::readTumTrajectory(path);
  if (trajectory.empty()) throw ltlo::InputError(path, 0, "no poses in the file");
  return trajectory;
}

}  // namespace

int main(int argc, char** argv) {
  ltlo::log::initFromEnvironment();
  CLI::App app{"ATE / RPE against ground truth and static-background IoU of masks"};
  std::string gt_path;
  std::string est_path;
  std::string gt_masks_dir;
  std::string est_masks_dir;
  std::string json_path;
  bool with_scale = false;
  double max_dt_s = 0.02;
  std::vector<std::string> world_from;
  app.add_option("--gt", gt_path, "ground-truth trajectory (TUM text, or EuRoC *.csv)")->required();
  app.add_option("--est", est_path, "estimated trajectory (TUM text, or EuRoC *.csv)")->required();
  app.add_option("--gt-masks", gt_masks_dir, "ground-truth masks/ folder (255 = dynamic)");
  app.add_option("--est-masks", est_masks_dir, "predicted masks folder (255 = dynamic)");
  app.add_option("--json", json_path, "also write the metrics to this JSON file");
  app.add_flag("--sim3", with_scale, "align with a similarity (scale) instead of SE3");
  app.add_option("--max-dt", max_dt_s, "timestamp association tolerance (s)")
      ->check(CLI::PositiveNumber);
  app.add_option("--world-from", world_from,
                 "GT0 EST0: --est is in the world of this earlier run (loaded atlas): also ATE with its alignment")
      ->expected(2);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "evaluate: " << e.what() << "\n" << app.help();
    return kBadInput;
  }
  if (gt_masks_dir.empty() != est_masks_dir.empty()) {
    std::cerr << "evaluate: --gt-masks and --est-masks go together (given: '" << gt_masks_dir
              << "' and '" << est_masks_dir << "')\n";
    return kBadInput;
  }

  try {
    const ltlo::io::Trajectory gt = readTrajectory(gt_path);
    const ltlo::io::Trajectory est = readTrajectory(est_path);
    const ltlo::eval::MatchedTrajectories matched =
        ltlo::eval::associateTrajectories(gt, est, max_dt_s);
    const int num_matched = static_cast<int>(matched.gt.size());
    if (num_matched < 3) {
      throw ltlo::InputError(est_path, 0,
                             "only " + std::to_string(num_matched) + " of " +
                                 std::to_string(est.size()) +
                                 " poses have a ground-truth pose in " + gt_path + " within " +
                                 std::to_string(max_dt_s) + " s, need at least 3");
    }
    const ltlo::eval::AteResult ate = ltlo::eval::computeAte(matched, with_scale);
    const ltlo::eval::RpeResult rpe = ltlo::eval::computeRpe(matched, ate.S_gt_est);

    ltlo::io::Metrics metrics;
    if (!world_from.empty()) {
      const ltlo::eval::MatchedTrajectories earlier =
          ltlo::eval::associateTrajectories(readTrajectory(world_from[0]), readTrajectory(world_from[1]), max_dt_s);
      if (earlier.gt.size() < 3) {
        throw ltlo::InputError(world_from[1], 0, "fewer than 3 poses matched to " + world_from[0] + " (--world-from)");
      }
      const ltlo::eval::AteResult earlier_ate = ltlo::eval::computeAte(earlier, with_scale);
      const ltlo::eval::AteResult fixed = ltlo::eval::computeAteFixed(matched, earlier_ate.S_gt_est);
      metrics.set("ate_fixed_rmse_m", fixed.error_m.rmse);
      metrics.set("ate_fixed_max_m", fixed.error_m.max);
      metrics.set("world_from_ate_rmse_m", earlier_ate.error_m.rmse);
    }
    metrics.set("ate_rmse_m", ate.error_m.rmse);
    metrics.set("rpe_trans_rmse_m_s", rpe.trans_m_s.rmse);
    metrics.set("rpe_rot_rmse_deg_s", rpe.rot_deg_s.rmse);
    if (!gt_masks_dir.empty()) {
      const ltlo::eval::MaskIouResult iou =
          ltlo::eval::evaluateMaskFolders(gt_masks_dir, est_masks_dir);
      metrics.set("static_iou", iou.mean_static_iou);
      metrics.set("static_iou_occluded", iou.mean_static_iou_occluded);
      metrics.set("num_mask_frames", iou.num_frames);
      metrics.set("num_occluded_frames", iou.num_occluded_frames);
      metrics.set("dynamic_recall", iou.dynamic_recall);
      metrics.set("static_share", iou.mean_static_share);
    }
    metrics.set("ate_mean_m", ate.error_m.mean);
    metrics.set("ate_median_m", ate.error_m.median);
    metrics.set("ate_max_m", ate.error_m.max);
    metrics.set("rpe_trans_rmse_m_frame", rpe.trans_m_frame.rmse);
    metrics.set("rpe_trans_mean_m_frame", rpe.trans_m_frame.mean);
    metrics.set("rpe_rot_rmse_deg_frame", rpe.rot_deg_frame.rmse);
    metrics.set("alignment_sim3", with_scale ? 1 : 0);  // numbers only: scripts parse floats
    metrics.set("alignment_scale", ate.S_gt_est.scale());
    metrics.set("num_gt", static_cast<int>(gt.size()));
    metrics.set("num_est", static_cast<int>(est.size()));
    metrics.set("num_matched", num_matched);
    std::cout << metrics.toText();
    if (!json_path.empty()) metrics.writeJson(json_path);
  } catch (const ltlo::InputError& e) {
    std::cerr << "evaluate: " << e.what() << "\n";
    return kBadInput;
  } catch (const std::exception& e) {
    std::cerr << "evaluate: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
