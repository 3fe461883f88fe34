#include "ltlo/report/benchmark_report.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/eval/mask_iou.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/io/trajectory_io.h"
#include "ltlo/report/plot.h"

namespace ltlo::report {
namespace {

namespace fs = std::filesystem;

constexpr double kOccludedShare = 0.40;  // a frame is "occluded" above this dynamic share
const cv::Scalar kGroundTruth(60, 170, 60);
const cv::Scalar kEstimate(40, 60, 220);
const cv::Scalar kOccludedMark(0, 150, 255);
const cv::Scalar kOccludedShade(215, 235, 255);
const cv::Scalar kError(170, 90, 30);
const cv::Scalar kIou(60, 150, 60);

int scenarioRank(const std::string& scenario) {
  static const std::vector<std::string> order = {"static", "stlo", "mtlo", "ltlo", "carried"};
  const auto it = std::find(order.begin(), order.end(), scenario);
  return it == order.end() ? static_cast<int>(order.size()) : static_cast<int>(it - order.begin());
}

std::string readFirstLine(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open");
  std::string line;
  std::getline(in, line);
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
  return line;
}

// "<stem>.png" files of a folder by name.
std::map<std::string, std::string> pngFiles(const std::string& dir) {
  std::map<std::string, std::string> files;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return files;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() == ".png") files[entry.path().stem().string()] = entry.path();
  }
  return files;
}

// Dynamic pixel share of every mask of the sequence (time order), cached as "t share" lines.
void dynamicShares(const std::string& sequence_dir, const std::string& cache_path,
                   std::vector<double>* t_s, std::vector<double>* share) {
  std::ifstream cached(cache_path);
  double t = 0.0, s = 0.0;
  while (cached >> t >> s) {
    t_s->push_back(t);
    share->push_back(s);
  }
  if (!t_s->empty()) return;
  for (const auto& [stem, path] : pngFiles(sequence_dir + "/masks")) {
    const cv::Mat mask = cv::imread(path, cv::IMREAD_UNCHANGED);
    if (mask.empty() || mask.type() != CV_8UC1) throw InputError(path, 0, "not an 8-bit mask");
    t_s->push_back(std::stod(stem));
    share->push_back(static_cast<double>(cv::countNonZero(mask >= 128)) / mask.total());
  }
  std::vector<std::size_t> order(t_s->size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return (*t_s)[a] < (*t_s)[b]; });
  std::vector<double> t_sorted, s_sorted;
  for (std::size_t i : order) {
    t_sorted.push_back((*t_s)[i]);
    s_sorted.push_back((*share)[i]);
  }
  *t_s = t_sorted;
  *share = s_sorted;
  std::error_code ec;
  fs::create_directories(fs::path(cache_path).parent_path(), ec);
  std::ofstream out(cache_path);
  for (std::size_t i = 0; i < t_s->size(); ++i) {
    out << cv::format("%.6f %.6f\n", (*t_s)[i], (*share)[i]);
  }
}

std::string number(std::optional<double> value, const char* format) {
  if (!value || !std::isfinite(*value)) return "n/a";
  return cv::format(format, *value);
}

double mean(const std::vector<double>& values) {
  double sum = 0.0;
  int n = 0;
  for (double v : values) {
    if (std::isfinite(v)) {
      sum += v;
      ++n;
    }
  }
  return n > 0 ? sum / n : NAN;
}

// Occluded stretches [t0, t1) of a per-frame share series.
std::vector<std::pair<double, double>> occludedStretches(const std::vector<double>& t_s,
                                                         const std::vector<double>& share,
                                                         double t0_s) {
  std::vector<std::pair<double, double>> stretches;
  for (std::size_t i = 0; i < t_s.size(); ++i) {
    if (share[i] <= kOccludedShare) continue;
    const double dt = i + 1 < t_s.size() ? t_s[i + 1] - t_s[i] : 1.0 / 30.0;
    const double a = t_s[i] - t0_s, b = a + dt;
    if (!stretches.empty() && std::abs(stretches.back().second - a) < 1e-6) {
      stretches.back().second = b;
    } else {
      stretches.emplace_back(a, b);
    }
  }
  return stretches;
}

}  // namespace

std::vector<RunRecord> findRuns(const std::string& benchmark_dir) {
  std::vector<RunRecord> runs;
  const fs::path runs_dir = fs::path(benchmark_dir) / "runs";
  std::error_code ec;
  if (!fs::is_directory(runs_dir, ec)) return runs;
  for (const fs::directory_entry& sequence : fs::directory_iterator(runs_dir)) {
    if (!sequence.is_directory()) continue;
    for (const fs::directory_entry& variant : fs::directory_iterator(sequence.path())) {
      const fs::path dir = variant.path();
      if (!variant.is_directory() || !fs::is_regular_file(dir / "metrics.json", ec) ||
          !fs::is_regular_file(dir / "trajectory.txt", ec)) {
        continue;
      }
      RunRecord run;
      run.sequence_name = sequence.path().filename().string();
      run.variant = dir.filename().string();
      run.run_dir = dir.string();
      run.sequence_dir = readFirstLine((dir / "sequence_path.txt").string());
      if (!fs::is_directory(run.sequence_dir, ec)) {  // no ground truth: ATE and IoU would be silently missing
        throw InputError((dir / "sequence_path.txt").string(), 1,
                         "sequence folder '" + run.sequence_dir + "' does not exist");
      }
      run.metrics = FlatJson::read((dir / "metrics.json").string());
      if (fs::is_regular_file(dir / "recon" / "reconstruct.json", ec)) {
        run.recon = FlatJson::read((dir / "recon" / "reconstruct.json").string());
      }
      if (fs::is_regular_file(dir / "recon" / "check.json", ec)) {
        run.recon_check = FlatJson::read((dir / "recon" / "check.json").string());
      }
      if (fs::is_regular_file(dir / "check_loops.txt", ec)) {
        std::ifstream in(dir / "check_loops.txt");
        run.false_loops = 0;
        for (std::string line; std::getline(in, line);) run.false_loops += line.rfind("FALSE", 0) == 0 ? 1 : 0;
      }
      const std::size_t at = run.sequence_name.rfind("_s");
      run.scenario = run.sequence_name;
      if (at != std::string::npos) {
        try {
          run.seed = std::stoi(run.sequence_name.substr(at + 2));
          run.scenario = run.sequence_name.substr(0, at);
        } catch (const std::exception&) {
          run.seed = 0;
        }
      }
      runs.push_back(std::move(run));
    }
  }
  std::sort(runs.begin(), runs.end(), [](const RunRecord& a, const RunRecord& b) {
    return std::make_tuple(scenarioRank(a.scenario), a.scenario, a.seed, a.variant) <
           std::make_tuple(scenarioRank(b.scenario), b.scenario, b.seed, b.variant);
  });
  return runs;
}

RunSeries loadSeries(const RunRecord& run, const std::string& cache_dir) {
  RunSeries series;
  const io::Trajectory est = io::readTumTrajectory(run.run_dir + "/trajectory.txt");
  const std::string gt_path = run.sequence_dir + "/groundtruth.txt";
  std::error_code ec;
  double t0_s = est.empty() ? 0.0 : est.front().t_s;
  if (fs::is_regular_file(gt_path, ec)) {
    const io::Trajectory gt = io::readTumTrajectory(gt_path);
    if (!gt.empty()) t0_s = gt.front().t_s;
    const eval::MatchedTrajectories matched = eval::associateTrajectories(gt, est);
    if (matched.gt.size() >= 3) {
      const eval::AteResult ate = eval::computeAte(matched, /*with_scale=*/false);
      series.ate_rmse_m = ate.error_m.rmse;
      for (std::size_t k = 0; k < matched.gt.size(); ++k) {
        const Vec3 g = matched.gt[k].T_w_x.translation();
        const Vec3 e = ate.S_gt_est * matched.est[k].T_w_x.translation();
        series.t_s.push_back(matched.gt[k].t_s - t0_s);
        series.gt_w.push_back(g);
        series.est_w.push_back(e);
        series.error_m.push_back((g - e).norm());
      }
    }
  }
  dynamicShares(run.sequence_dir, cache_dir + "/" + run.sequence_name + "_dynamic.txt",
                &series.frame_t_s, &series.dynamic_share);
  for (double& t : series.frame_t_s) t -= t0_s;

  // Static IoU per frame of the run's segmentation against the ground-truth masks.
  const std::map<std::string, std::string> est_masks = pngFiles(run.run_dir + "/segmentation");
  if (!est_masks.empty()) {
    const std::map<std::string, std::string> gt_masks = pngFiles(run.sequence_dir + "/masks");
    std::vector<double> occluded;
    std::vector<std::pair<double, double>> t_iou;  // (t - t0 s, IoU); the map orders stems as text
    for (const auto& [stem, est_path] : est_masks) {
      auto gt = gt_masks.find(stem);
      if (gt == gt_masks.end()) continue;
      const cv::Mat g = cv::imread(gt->second, cv::IMREAD_UNCHANGED);
      const cv::Mat e = cv::imread(est_path, cv::IMREAD_UNCHANGED);
      if (g.empty() || e.empty() || g.size() != e.size() || g.type() != CV_8UC1 ||
          e.type() != CV_8UC1) {
        throw InputError(est_path, 0, "not an 8-bit mask of the ground truth's size");
      }
      const double iou = eval::staticIou(g, e);
      t_iou.emplace_back(std::stod(stem) - t0_s, iou);
      if (static_cast<double>(cv::countNonZero(g >= 128)) / g.total() > kOccludedShare) {
        occluded.push_back(iou);
      }
    }
    // In time order for the plot ("10.0" sorts before "9.9" as text).
    std::sort(t_iou.begin(), t_iou.end());
    for (const auto& [t_s, iou] : t_iou) {
      series.iou_t_s.push_back(t_s);
      series.iou.push_back(iou);
    }
    if (!series.iou.empty()) series.mean_iou = mean(series.iou);
    if (!occluded.empty()) series.mean_iou_occluded = mean(occluded);
  }
  return series;
}

cv::Mat runFigure(const RunRecord& run, const RunSeries& series) {
  const std::string name = run.sequence_name + " " + run.variant;
  const double t0 = series.frame_t_s.empty() ? 0.0 : series.frame_t_s.front();
  const std::vector<std::pair<double, double>> occluded =
      occludedStretches(series.frame_t_s, series.dynamic_share, 0.0);
  double t_end = series.t_s.empty() ? 1.0 : series.t_s.back();
  if (!series.frame_t_s.empty()) t_end = std::max(t_end, series.frame_t_s.back());

  // (a) Top view in the ground truth's x-y plane.
  Plot top(800, 500, "trajectory (top view): " + name);
  if (series.gt_w.empty()) {
    top.setAxes(0, 1, 0, 1, "x (m)", "y (m)");
    top.note("no ground truth matched to the trajectory");
  } else {
    double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
    for (const std::vector<Vec3>* path : {&series.gt_w, &series.est_w}) {
      for (const Vec3& p : *path) {
        x0 = std::min(x0, p.x());
        x1 = std::max(x1, p.x());
        y0 = std::min(y0, p.y());
        y1 = std::max(y1, p.y());
      }
    }
    const double margin = 0.05 * std::max(x1 - x0, y1 - y0) + 0.1;
    top.setAxes(x0 - margin, x1 + margin, y0 - margin, y1 + margin, "x (m)", "y (m)", true);
    std::vector<double> gx, gy, ex, ey, ox, oy;
    for (std::size_t k = 0; k < series.gt_w.size(); ++k) {
      gx.push_back(series.gt_w[k].x());
      gy.push_back(series.gt_w[k].y());
      ex.push_back(series.est_w[k].x());
      ey.push_back(series.est_w[k].y());
      // Occluded stretches of the ground-truth path (nearest frame's dynamic share).
      bool is_occluded = false;
      for (const auto& [a, b] : occluded) is_occluded |= series.t_s[k] >= a && series.t_s[k] < b;
      ox.push_back(is_occluded ? gx.back() : NAN);
      oy.push_back(is_occluded ? gy.back() : NAN);
    }
    top.line(ox, oy, kOccludedMark, 9);
    top.line(gx, gy, kGroundTruth, 2);
    top.line(ex, ey, kEstimate, 2);
    top.marker(gx.front(), gy.front(), kGroundTruth, 7);
    top.addLegend("ground truth", kGroundTruth);
    top.addLegend(cv::format("estimate (ATE %.3f m)", series.ate_rmse_m), kEstimate);
    top.addLegend("> 40 % dynamic", kOccludedMark);
  }

  // (b) Position error over time.
  double max_error = 0.0;
  for (double e : series.error_m) max_error = std::max(max_error, e);
  Plot error(800, 500, "position error after alignment: " + name);
  error.setAxes(t0, t_end, 0.0, max_error > 0 ? 1.1 * max_error : 0.01, "time (s)", "error (m)");
  for (const auto& [a, b] : occluded) error.shadeX(a, b, kOccludedShade);
  error.line(series.t_s, series.error_m, kError, 2);
  error.addLegend("|p_gt - p_est|", kError);
  error.addLegend("> 40 % dynamic", kOccludedShade);
  if (series.error_m.empty()) error.note("no ground truth matched to the trajectory");

  // (c) IoU over time.
  Plot iou(800, 500, "static-background IoU per frame: " + name);
  iou.setAxes(t0, t_end, 0.0, 1.02, "time (s)", "static IoU");
  for (const auto& [a, b] : occluded) iou.shadeX(a, b, kOccludedShade);
  if (series.iou.empty()) {
    iou.note("no segmentation/ in this run");
  } else {
    iou.line(series.iou_t_s, series.iou, kIou, 2);
    iou.addLegend(cv::format("IoU (mean %.3f)", series.mean_iou), kIou);
    iou.addLegend("> 40 % dynamic", kOccludedShade);
  }

  // (d) Per-stage timing.
  std::vector<std::string> stages;
  for (const auto& [key, value] : run.metrics.numbers()) {
    const std::string suffix = "_median_ms";
    if (key.size() > suffix.size() &&
        key.compare(key.size() - suffix.size(), suffix.size(), suffix) == 0) {
      stages.push_back(key.substr(0, key.size() - suffix.size()));
    }
  }
  std::vector<double> medians, p95s;
  for (const std::string& stage : stages) {
    medians.push_back(run.metrics.number(stage + "_median_ms").value_or(NAN));
    p95s.push_back(run.metrics.number(stage + "_p95_ms").value_or(NAN));
  }
  const cv::Mat timing = barChart(
      800, 500, "time per call: " + name, "ms", stages,
      {{"median", cv::Scalar(180, 120, 40), medians}, {"p95", cv::Scalar(110, 190, 240), p95s}});
  return grid({{top.render(), error.render()}, {iou.render(), timing}});
}

namespace {

// One run of the report: its record, series and figure (relative to the benchmark folder).
struct Row {
  const RunRecord* run;
  RunSeries series;
  std::string plot;
};

// Loads every run's series and writes its figure to plots/.
std::vector<Row> plotRuns(const std::vector<RunRecord>& runs, const std::string& benchmark_dir,
                          const std::string& cache_dir) {
  std::vector<Row> rows;
  for (const RunRecord& run : runs) {
    Row row{&run, loadSeries(run, cache_dir), ""};
    row.plot = "plots/" + run.sequence_name + "_" + run.variant + ".png";
    if (!cv::imwrite(benchmark_dir + "/" + row.plot, runFigure(run, row.series))) {
      throw InputError(benchmark_dir + "/" + row.plot, 0, "cannot write image");
    }
    log::info("report: ", run.sequence_name, " ", run.variant, " plotted");
    rows.push_back(std::move(row));
  }
  return rows;
}

void writeIntroduction(std::ostringstream& md, const std::string& title, std::size_t num_runs) {
  md << "# LTLO-SLAM benchmark\n\n" << title << "\n\n";
  md << num_runs
     << " runs. Variants: `rgbd_inertial` (the full system), `rgbd_only` (`--no-imu`), "
     << "`seg_off` (`Seg.Enable = 0`: every pixel static). ATE: RMSE after SE3 alignment of the "
     << "whole trajectory; RPE per second; static IoU: the run's segmentation/ against the "
     << "sequence's masks/, over all frames and over frames more than 40 % dynamic (\"occl.\"); "
     << "n/a where a run has no segmentation/. Reconstruction: `reconstruct` with the run's own "
     << "trajectory and segmentation, checked by `check_surfels` (accuracy: share of surfel area "
     << "within 3 cm of scene.ply; boxes: share on moving objects; completeness: share of the "
     << "static surface seen at <= 80 deg covered within 3 cm).\n\n";
}

// Means per scenario and variant.
void writeSummaryTable(std::ostringstream& md, const std::vector<Row>& rows) {
  md << "## Summary (mean over seeds)\n\n";
  md << "| scenario | variant | runs | ATE RMSE (m) | ATE online (m) | RPE (m/s) | RPE (deg/s) | static IoU | "
        "IoU occl. | FPS | tracking median (ms) | peak memory (MB) | maps | loops |\n";
  md << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  std::map<std::pair<std::string, std::string>, std::vector<const Row*>> groups;
  std::vector<std::pair<std::string, std::string>> group_order;
  for (const Row& row : rows) {
    const auto key = std::make_pair(row.run->scenario, row.run->variant);
    if (!groups.count(key)) group_order.push_back(key);
    groups[key].push_back(&row);
  }
  auto metric = [](const Row& row, const char* key) {
    return row.run->metrics.number(key).value_or(NAN);
  };
  auto groupMean = [&](const std::vector<const Row*>& members, auto&& value) {
    std::vector<double> values;
    for (const Row* r : members) values.push_back(value(*r));
    return mean(values);
  };
  for (const auto& key : group_order) {
    const std::vector<const Row*>& g = groups[key];
    auto show = [](double v, const char* f) { return std::isfinite(v) ? cv::format(f, v) : "n/a"; };
    md << "| " << key.first << " | " << key.second << " | " << g.size() << " | "
       << show(groupMean(g, [](const Row& r) { return r.series.ate_rmse_m; }), "%.3f") << " | "
       << show(groupMean(g, [&](const Row& r) { return metric(r, "ate_online_rmse_m"); }), "%.3f") << " | "
       << show(groupMean(g, [&](const Row& r) { return metric(r, "rpe_trans_rmse_m_s"); }), "%.3f")
       << " | "
       << show(groupMean(g, [&](const Row& r) { return metric(r, "rpe_rot_rmse_deg_s"); }), "%.2f")
       << " | "
       << show(
              groupMean(
                  g, [](const Row& r) { return r.series.mean_iou >= 0 ? r.series.mean_iou : NAN; }),
              "%.3f")
       << " | "
       << show(groupMean(g,
                         [](const Row& r) {
                           return r.series.mean_iou_occluded >= 0 ? r.series.mean_iou_occluded
                                                                  : NAN;
                         }),
               "%.3f")
       << " | " << show(groupMean(g, [&](const Row& r) { return metric(r, "fps"); }), "%.1f")
       << " | "
       << show(groupMean(g, [&](const Row& r) { return metric(r, "tracking_frame_median_ms"); }),
               "%.1f")
       << " | "
       << show(groupMean(g, [&](const Row& r) { return metric(r, "peak_memory_mb"); }), "%.0f")
       << " | " << show(groupMean(g, [&](const Row& r) { return metric(r, "maps"); }), "%.1f")
       << " | " << show(groupMean(g, [&](const Row& r) { return metric(r, "loops"); }), "%.1f")
       << " |\n";
  }
}

void writeAllRunsTable(std::ostringstream& md, const std::vector<Row>& rows) {
  md << "\n## All runs\n\n";
  md << "| sequence | variant | ATE RMSE (m) | ATE online (m) | RPE (m/s) | RPE (deg/s) | static IoU | IoU occl. | "
        "FPS | tracking median (ms) | peak memory (MB) | maps | loops | merges | wall (s) |\n";
  md << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const Row& row : rows) {
    const FlatJson& m = row.run->metrics;
    md << "| " << row.run->sequence_name << " | " << row.run->variant << " | "
       << cv::format("%.3f", row.series.ate_rmse_m) << " | " << number(m.number("ate_online_rmse_m"), "%.3f")
       << " | " << number(m.number("rpe_trans_rmse_m_s"), "%.3f") << " | "
       << number(m.number("rpe_rot_rmse_deg_s"), "%.2f") << " | "
       << (row.series.mean_iou >= 0 ? cv::format("%.3f", row.series.mean_iou) : "n/a") << " | "
       << (row.series.mean_iou_occluded >= 0 ? cv::format("%.3f", row.series.mean_iou_occluded)
                                             : "n/a")
       << " | " << number(m.number("fps"), "%.1f") << " | "
       << number(m.number("tracking_frame_median_ms"), "%.1f") << " | "
       << number(m.number("peak_memory_mb"), "%.0f") << " | " << number(m.number("maps"), "%.0f")
       << " | " << number(m.number("loops"), "%.0f") << " | " << number(m.number("merges"), "%.0f")
       << " | " << number(m.number("wall_s"), "%.1f") << " |\n";
  }
}

// The scenarios beyond the five occlusion profiles (issue 32's harder worlds, named in
// scripts/scenarios.sh's catalogue): the figures their acceptance is stated in. Only when there are some.
void writeHarderWorldsTable(std::ostringstream& md, const std::vector<Row>& rows) {
  const int num_profiles = scenarioRank("");
  bool any = false;
  for (const Row& row : rows) any |= scenarioRank(row.run->scenario) == num_profiles;
  if (!any) return;
  md << "\n## Harder worlds\n\n"
     << "Scenarios beyond the occlusion profiles: an occluded or still start, a standstill among "
     << "movers, texture-less movers, walking figures and a door, several movers at once, runs of "
     << "minutes (`scripts/scenarios.sh` lists each one's simulator options). Dynamic recall: share of "
     << "the ground truth's dynamic pixels labelled dynamic; false loops: loops and merges "
     << "`scripts/check_loops.py` found false; mapping last/first minute: median "
     << "mapping time per keyframe in the last minute over the first (runs of two minutes or more), as wall "
     << "time and as the mapping thread's CPU time (its own work, without the waits for the cores).\n\n";
  md << "| sequence | variant | ATE RMSE (m) | ATE online (m) | frames without pose | maps | static IoU | "
        "dynamic recall | loops | merges | false loops | keyframes | peak memory (MB) | mapping last/first minute | "
        "mapping CPU last/first minute |\n";
  md << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const Row& row : rows) {
    if (scenarioRank(row.run->scenario) != num_profiles) continue;
    const FlatJson& m = row.run->metrics;
    md << "| " << row.run->sequence_name << " | " << row.run->variant << " | "
       << cv::format("%.3f", row.series.ate_rmse_m) << " | " << number(m.number("ate_online_rmse_m"), "%.3f")
       << " | " << number(m.number("frames_without_pose"), "%.0f") << " | " << number(m.number("maps"), "%.0f")
       << " | " << (row.series.mean_iou >= 0 ? cv::format("%.3f", row.series.mean_iou) : "n/a") << " | "
       << number(m.number("dynamic_recall"), "%.3f") << " | " << number(m.number("loops"), "%.0f") << " | "
       << number(m.number("merges"), "%.0f") << " | "
       << (row.run->false_loops >= 0 ? std::to_string(row.run->false_loops) : std::string("n/a")) << " | "
       << number(m.number("keyframes"), "%.0f") << " | " << number(m.number("peak_memory_mb"), "%.0f") << " | "
       << number(m.number("mapping_keyframe_last_to_first_minute"), "%.2f") << " | "
       << number(m.number("mapping_keyframe_cpu_last_to_first_minute"), "%.2f") << " |\n";
  }
}

// Only when some run has a reconstruction.
// Runs played at the camera's pace (benchmark.sh RATE, rgbd_inertial --rate): did tracking keep up?
// Only when there are some.
void writeRealTimeTable(std::ostringstream& md, const std::vector<Row>& rows) {
  bool any = false;
  for (const Row& row : rows) any |= row.run->metrics.number("rate").has_value();
  if (!any) return;
  md << "\n## Real time\n\n"
     << "Runs played at R times their recorded speed (`scripts/benchmark.sh` `RATE`, `rgbd_inertial --rate`), "
     << "as a live camera delivers them: late frames started more than one frame interval after they were "
     << "due (tracked all the same, never dropped); lag: how long after.\n\n";
  md << "| sequence | variant | rate | late frames | late share | lag mean (ms) | lag max (ms) | "
        "tracking median (ms) | tracking p95 (ms) |\n";
  md << "|---|---|---|---|---|---|---|---|---|\n";
  for (const Row& row : rows) {
    const FlatJson& m = row.run->metrics;
    if (!m.number("rate")) continue;
    md << "| " << row.run->sequence_name << " | " << row.run->variant << " | " << number(m.number("rate"), "%g")
       << " | " << number(m.number("late_frames"), "%.0f") << " | " << number(m.number("late_frame_share"), "%.3f")
       << " | " << number(m.number("lag_mean_ms"), "%.1f") << " | " << number(m.number("lag_max_ms"), "%.1f")
       << " | " << number(m.number("tracking_frame_median_ms"), "%.1f") << " | "
       << number(m.number("tracking_frame_p95_ms"), "%.1f") << " |\n";
  }
}

void writeReconstructionTable(std::ostringstream& md, const std::vector<Row>& rows) {
  bool any_recon = false;
  for (const Row& row : rows) any_recon |= row.run->recon.has_value();
  if (!any_recon) return;
  md << "\n## Reconstruction\n\n";
  md << "| sequence | variant | surfels | accuracy (3 cm) | on moving boxes | completeness | "
        "pixels fused | recon wall (s) | recon CPU (s) | peak memory (MB) |\n";
  md << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (const Row& row : rows) {
    if (!row.run->recon) continue;
    const FlatJson& r = *row.run->recon;
    const std::optional<FlatJson>& c = row.run->recon_check;
    auto check = [&](const char* key) { return c ? c->number(key) : std::optional<double>(); };
    md << "| " << row.run->sequence_name << " | " << row.run->variant << " | "
       << number(r.number("surfels"), "%.0f") << " | "
       << number(check("accuracy").has_value() ? std::optional<double>(100 * *check("accuracy"))
                                               : std::nullopt,
                 "%.2f %%")
       << " | "
       << number(check("dynamic_area_fraction").has_value()
                     ? std::optional<double>(100 * *check("dynamic_area_fraction"))
                     : std::nullopt,
                 "%.2f %%")
       << " | "
       << number(check("completeness").has_value()
                     ? std::optional<double>(100 * *check("completeness"))
                     : std::nullopt,
                 "%.1f %%")
       << " | " << (r.number("all_pixels").value_or(0) > 0 ? "all with depth" : "static") << " | "
       << number(r.number("wall_s"), "%.1f") << " | " << number(r.number("cpu_s"), "%.1f")
       << " | " << number(r.number("peak_memory_mb"), "%.0f") << " |\n";
  }
}

// The figures by scenario, each run's reconstruction snapshot after its figure when there is one.
void writePlotsSection(std::ostringstream& md, const std::vector<Row>& rows,
                       const std::string& benchmark_dir) {
  md << "\n## Plots\n\nPer run: trajectory top view (ground truth green, aligned estimate red, "
        "orange where more than 40 % of the pixels are dynamic), position error over time "
        "(occluded "
        "frames shaded), static IoU over time, time per call of each stage (median, p95).\n";
  std::error_code ec;
  std::string scenario;
  for (const Row& row : rows) {
    if (row.run->scenario != scenario) {
      scenario = row.run->scenario;
      md << "\n### " << scenario << "\n";
    }
    md << "\n**" << row.run->sequence_name << " " << row.run->variant << "**\n\n!["
       << row.run->sequence_name << " " << row.run->variant << "](" << row.plot << ")\n";
    const std::string bird = row.run->run_dir + "/recon/snapshots/bird_eye.png";
    if (fs::is_regular_file(bird, ec)) {
      md << "\n![reconstruction " << row.run->sequence_name << "]("
         << fs::relative(bird, benchmark_dir).string() << ")\n";
    }
  }
}

}  // namespace

int writeBenchmarkReport(const std::string& benchmark_dir, const std::string& title) {
  std::error_code exists_ec;
  if (!fs::is_directory(fs::path(benchmark_dir) / "runs", exists_ec)) {
    throw InputError(benchmark_dir, 0, "no runs/ folder (not a scripts/benchmark.sh output folder)");
  }
  const std::vector<RunRecord> runs = findRuns(benchmark_dir);
  const std::string plots_dir = benchmark_dir + "/plots";
  const std::string cache_dir = benchmark_dir + "/cache";
  std::error_code ec;
  fs::create_directories(plots_dir, ec);
  if (ec) throw InputError(plots_dir, 0, "cannot create folder (" + ec.message() + ")");
  const std::vector<Row> rows = plotRuns(runs, benchmark_dir, cache_dir);

  std::ostringstream md;
  writeIntroduction(md, title, runs.size());
  writeSummaryTable(md, rows);
  writeAllRunsTable(md, rows);
  writeHarderWorldsTable(md, rows);
  writeRealTimeTable(md, rows);
  writeReconstructionTable(md, rows);
  writePlotsSection(md, rows, benchmark_dir);
  const std::string path = benchmark_dir + "/report.md";
  std::ofstream out(path);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  out << md.str();
  if (!out) throw InputError(path, 0, "write failed");
  return static_cast<int>(rows.size());
}

}  // namespace ltlo::report
