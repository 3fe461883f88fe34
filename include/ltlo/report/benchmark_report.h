#pragma once
/// The benchmark report (scripts/benchmark.sh): reads every finished run under
/// OUT/runs/<sequence>/<variant>/ and writes OUT/report.md with tables and OUT/plots/*.png:
///   - per run: trajectory top view (estimate aligned to ground truth, SE3 Umeyama; stretches with
///     more than 40 % dynamic pixels marked), position error over time with the occluded frames
///     shaded, static-background IoU over time (when the run wrote segmentation/), per-stage
///     timing (median and p95 from metrics.json);
///   - tables: per run, means per scenario and variant, and the reconstructions.
/// A run folder holds the SLAM outputs (trajectory.txt, metrics.json, optionally segmentation/),
/// sequence_path.txt (the sequence folder) and optionally recon/ (reconstruct.json, check.json,
/// snapshots/). Per-frame dynamic shares of a sequence are cached in OUT/cache/.
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/report/flat_json.h"

namespace ltlo::report {

struct RunRecord {
  std::string sequence_name;  ///< folder name, e.g. ltlo_s1
  std::string scenario;       ///< the name before "_s<seed>" (the whole name otherwise)
  int seed = 0;
  std::string variant;
  std::string run_dir;
  std::string sequence_dir;
  FlatJson metrics;                     ///< metrics.json
  std::optional<FlatJson> recon;        ///< recon/reconstruct.json
  std::optional<FlatJson> recon_check;  ///< recon/check.json
  /// Loops and merges scripts/check_loops.py found false (lines starting "FALSE" in check_loops.txt,
  /// written by scripts/benchmark.sh); -1 without that file.
  int false_loops = -1;
};

/// Finished runs (metrics.json and trajectory.txt present), sorted by scenario order (static,
/// stlo, mtlo, ltlo, carried, then others by name), seed and variant. Throws InputError naming
/// the file when a run's sequence_path.txt or metrics.json is unreadable.
std::vector<RunRecord> findRuns(const std::string& benchmark_dir);

/// Per-frame series of one run, times relative to the first ground-truth pose (s).
struct RunSeries {
  std::vector<double> t_s;      ///< matched poses
  std::vector<Vec3> gt_w;       ///< ground-truth positions
  std::vector<Vec3> est_w;      ///< estimate aligned to the ground truth
  std::vector<double> error_m;  ///< |gt - aligned estimate|
  double ate_rmse_m = 0.0;
  std::vector<double> frame_t_s;      ///< every frame of the sequence
  std::vector<double> dynamic_share;  ///< ground-truth dynamic pixel share per frame (masks/)
  std::vector<double> iou_t_s;        ///< frames with a segmentation mask
  std::vector<double> iou;            ///< static IoU per frame
  double mean_iou = -1.0;             ///< < 0 without segmentation
  double mean_iou_occluded = -1.0;    ///< over frames more than 40 % dynamic; < 0 when none
};

/// Loads the trajectory, ground truth, masks and segmentation of a run (cache_dir for the
/// per-sequence dynamic shares). Throws InputError naming a bad file.
RunSeries loadSeries(const RunRecord& run, const std::string& cache_dir);

/// The four-panel figure of one run (1600 x 1000 px).
cv::Mat runFigure(const RunRecord& run, const RunSeries& series);

/// Writes report.md and plots/ for every finished run; returns the number of runs reported.
/// `title` is the report's first line (e.g. date and commit). Throws InputError naming the folder
/// when it has no runs/ folder.
int writeBenchmarkReport(const std::string& benchmark_dir, const std::string& title);

}  // namespace ltlo::report
