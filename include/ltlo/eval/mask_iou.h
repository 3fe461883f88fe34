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
  /// average static IoU over the frames whose ground truth is more than `occluded_fraction`
  /// dynamic (0 when there is none)
  double mean_static_iou_occluded = 0.0;
  int num_occluded_frames = 0;
  /// share of all ground-truth dynamic pixels (over all frames) that the estimate calls dynamic;
  /// 1 when the ground truth has no dynamic pixel (the carried box's "dynamic while carried")
  double dynamic_recall = 1.0;
  /// average share of static pixels in the estimated masks (a static sequence: >= 0.99)
  double mean_static_share = 1.0;
};

/// Ground-truth masks more dynamic than this count as occluded frames (the thesis's "large
/// occlusion": more than 40 % of the image).
inline constexpr double kOccludedFraction = 0.4;

/// Matches <timestamp>.png files of the two folders by the number in the name (within
/// max_dt_s) and averages staticIou (all frames and the occluded ones), the dynamic recall and the
/// static share. Throws InputError naming the file for a missing folder, a name that is not a
/// timestamp, an unreadable or non-8-bit-1-channel PNG, mismatched sizes, or no frame in common.
MaskIouResult evaluateMaskFolders(const std::string& gt_dir, const std::string& est_dir,
                                  double max_dt_s = 1e-4, double occluded_fraction = kOccludedFraction);

}  // namespace ltlo::eval
