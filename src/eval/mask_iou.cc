#include "ltlo/eval/mask_iou.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <utility>
#include <vector>

#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/io/associate.h"

namespace ltlo::eval {
namespace {

namespace fs = std::filesystem;

// (timestamp from the file name, path) of every PNG in the folder, sorted by time.
std::vector<std::pair<double, std::string>> listMasks(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw InputError(dir, 0, "mask folder does not exist");
  std::vector<std::pair<double, std::string>> masks;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file() || entry.path().extension() != ".png") continue;
    const std::string stem = entry.path().stem().string();
    char* end = nullptr;
    const double t_s = std::strtod(stem.c_str(), &end);
    if (stem.empty() || *end != '\0' || !std::isfinite(t_s)) {
      throw InputError(entry.path().string(), 0,
                       "mask file name is not a timestamp: '" + stem + "'");
    }
    masks.emplace_back(t_s, entry.path().string());
  }
  std::sort(masks.begin(), masks.end());
  return masks;
}

cv::Mat loadMask(const std::string& path) {
  cv::Mat mask;
  try {
    mask = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    throw InputError(path, 0, "cannot decode mask (" + e.msg + ")");
  }
  if (mask.empty()) throw InputError(path, 0, "cannot read mask image");
  if (mask.type() != CV_8UC1) {
    std::ostringstream os;
    os << "expected an 8-bit 1-channel mask, found " << mask.channels() << " channel(s) of "
       << (mask.elemSize1() * 8) << "-bit";
    throw InputError(path, 0, os.str());
  }
  return mask;
}

}  // namespace

double staticIou(const cv::Mat& gt_mask, const cv::Mat& est_mask) {
  LTLO_ASSERT(gt_mask.type() == CV_8UC1 && est_mask.type() == CV_8UC1, "masks must be CV_8UC1");
  LTLO_ASSERT(gt_mask.size() == est_mask.size(), "mask sizes differ");
  int64_t intersection = 0;
  int64_t union_count = 0;
  for (int v = 0; v < gt_mask.rows; ++v) {
    const uint8_t* gt_row = gt_mask.ptr<uint8_t>(v);
    const uint8_t* est_row = est_mask.ptr<uint8_t>(v);
    for (int u = 0; u < gt_mask.cols; ++u) {
      const bool gt_static = gt_row[u] < 128;
      const bool est_static = est_row[u] < 128;
      intersection += gt_static && est_static;
      union_count += gt_static || est_static;
    }
  }
  if (union_count == 0) return 1.0;
  return static_cast<double>(intersection) / static_cast<double>(union_count);
}

MaskIouResult evaluateMaskFolders(const std::string& gt_dir, const std::string& est_dir,
                                  double max_dt_s, double occluded_fraction) {
  const std::vector<std::pair<double, std::string>> gt = listMasks(gt_dir);
  const std::vector<std::pair<double, std::string>> est = listMasks(est_dir);
  std::vector<double> gt_times_s;
  std::vector<double> est_times_s;
  for (const auto& mask : gt) gt_times_s.push_back(mask.first);
  for (const auto& mask : est) est_times_s.push_back(mask.first);
  const std::vector<std::pair<int, int>> pairs =
      io::associateTimestamps(gt_times_s, est_times_s, max_dt_s);
  MaskIouResult result;
  result.num_gt = static_cast<int>(gt.size());
  result.num_est = static_cast<int>(est.size());
  if (pairs.empty()) {
    throw InputError(est_dir, 0,
                     "no mask file name matches a ground-truth mask timestamp in " + gt_dir + " (" +
                         std::to_string(est.size()) + " estimated, " + std::to_string(gt.size()) +
                         " ground-truth masks)");
  }
  double sum_iou = 0.0, sum_iou_occluded = 0.0, sum_static_share = 0.0;
  int64_t gt_dynamic = 0, found_dynamic = 0;
  for (const auto& [i, j] : pairs) {
    const cv::Mat gt_mask = loadMask(gt[i].second);
    const cv::Mat est_mask = loadMask(est[j].second);
    if (gt_mask.size() != est_mask.size()) {
      std::ostringstream os;
      os << "size " << est_mask.cols << "x" << est_mask.rows << " differs from " << gt_mask.cols
         << "x" << gt_mask.rows << " of " << gt[i].second;
      throw InputError(est[j].second, 0, os.str());
    }
    const double iou = staticIou(gt_mask, est_mask);
    sum_iou += iou;
    const cv::Mat gt_is_dynamic = gt_mask >= 128;
    const int frame_gt_dynamic = cv::countNonZero(gt_is_dynamic);
    gt_dynamic += frame_gt_dynamic;
    found_dynamic += cv::countNonZero(gt_is_dynamic & (est_mask >= 128));
    sum_static_share += static_cast<double>(cv::countNonZero(est_mask < 128)) / static_cast<double>(est_mask.total());
    if (frame_gt_dynamic > occluded_fraction * static_cast<double>(gt_mask.total())) {
      sum_iou_occluded += iou;
      ++result.num_occluded_frames;
    }
  }
  result.num_frames = static_cast<int>(pairs.size());
  result.mean_static_iou = sum_iou / result.num_frames;
  result.mean_static_iou_occluded =
      result.num_occluded_frames > 0 ? sum_iou_occluded / result.num_occluded_frames : 0.0;
  result.dynamic_recall = gt_dynamic > 0 ? static_cast<double>(found_dynamic) / static_cast<double>(gt_dynamic) : 1.0;
  result.mean_static_share = sum_static_share / result.num_frames;
  return result;
}

}  // namespace ltlo::eval
