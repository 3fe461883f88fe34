#pragma once
/// Static-background IoU of predicted dynamic masks against ground truth (DATA_FORMAT.md
/// masks/: 8-bit, 255 = dynamic, 0 = static).
#include <opencv2/core.hpp>
#include <string>

namespace ltlo::eval {

/// IoU of the static class (pixel value < 128) of two CV_8UC1 masks of equal size:
/// |static_gt AND static_est| / |static_gt OR static_est|; 1 when neither has a static pixel.
double staticIou(const cv::Mat& gt_mask, const cv::Mat& est_mask);

struct MaskIouResult {
  double mean_static_iou = 0.0;  ///< average over frames present in both folders
  int num_frames = 0;            ///< frames present in both
  int num_gt = 0;                ///< PNG masks in the ground-truth folder
  int num_est = 0;               ///< PNG masks in the estimated folder
};

/// Matches <timestamp>.png files of the two folders by the number in the name (within
/// max_dt_s) and averages staticIou. Throws InputError naming the file for a missing folder, a
/// name that is not a timestamp, an unreadable or non-8-bit-1-channel PNG, mismatched sizes, or
/// no frame in common.
MaskIouResult evaluateMaskFolders(const std::string& gt_dir, const std::string& est_dir,
                                  double max_dt_s = 1e-4);

}  // namespace ltlo::eval
