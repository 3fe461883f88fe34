#include "ltlo/eval/mask_iou.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <opencv2/imgcodecs.hpp>

#include "expect_input_error.h"
#include "ltlo/core/errors.h"
#include "test_sequence_writer.h"

namespace ltlo::eval {
namespace {

namespace fs = std::filesystem;
using io::test::TempDir;
using ltlo::test::inputErrorOf;

// 4x4 masks: ground truth has a 2x2 dynamic block, the estimate a 2x3 block overlapping it in
// one column (numbers in StaticIou.HandMadeMasks).
cv::Mat gtMask() {
  cv::Mat mask(4, 4, CV_8UC1, cv::Scalar(0));
  mask(cv::Rect(0, 0, 2, 2)) = 255;
  return mask;
}
cv::Mat estMask() {
  cv::Mat mask(4, 4, CV_8UC1, cv::Scalar(0));
  mask(cv::Rect(1, 0, 3, 2)) = 255;  // columns 1..3 of rows 0..1
  return mask;
}

TEST(StaticIou, HandMadeMasks) {
  // Static gt: 16 - 4 = 12; static est: 16 - 6 = 10; dynamic union = rows 0..1, cols 0..3 = 8,
  // so static in both = 8 and static in either = 16 - |dyn_gt AND dyn_est| = 16 - 2 = 14.
  EXPECT_NEAR(staticIou(gtMask(), estMask()), 8.0 / 14.0, 1e-12);
  EXPECT_DOUBLE_EQ(staticIou(gtMask(), gtMask()), 1.0);
  const cv::Mat all_dynamic(4, 4, CV_8UC1, cv::Scalar(255));
  EXPECT_DOUBLE_EQ(staticIou(all_dynamic, all_dynamic), 1.0);
  EXPECT_DOUBLE_EQ(staticIou(cv::Mat(4, 4, CV_8UC1, cv::Scalar(0)), all_dynamic), 0.0);
}

TEST(StaticIou, FolderAverageOverCommonTimestamps) {
  TempDir tmp("eval_masks");
  fs::create_directories(tmp.file("gt"));
  fs::create_directories(tmp.file("est"));
  cv::imwrite(tmp.file("gt/1.000000.png"), gtMask());
  cv::imwrite(tmp.file("gt/1.100000.png"), gtMask());
  cv::imwrite(tmp.file("gt/1.200000.png"), gtMask());  // no estimate: not counted
  cv::imwrite(tmp.file("est/1.000000.png"), estMask());
  cv::imwrite(tmp.file("est/1.1.png"), gtMask());       // same time, other spelling
  cv::imwrite(tmp.file("est/5.000000.png"), gtMask());  // no ground truth: not counted
  const MaskIouResult result = evaluateMaskFolders(tmp.file("gt"), tmp.file("est"));
  EXPECT_EQ(result.num_frames, 2);
  EXPECT_EQ(result.num_gt, 3);
  EXPECT_EQ(result.num_est, 3);
  EXPECT_NEAR(result.mean_static_iou, 0.5 * (8.0 / 14.0 + 1.0), 1e-12);
}

// The occluded average (ground truth more than 40 % dynamic), the dynamic recall (pixel-weighted
// over all frames) and the estimate's static share.
TEST(StaticIou, OccludedFramesRecallAndStaticShare) {
  TempDir tmp("eval_masks_occluded");
  fs::create_directories(tmp.file("gt"));
  fs::create_directories(tmp.file("est"));
  cv::Mat occluded(4, 4, CV_8UC1, cv::Scalar(0));
  occluded(cv::Rect(0, 0, 4, 2)) = 255;  // 8 of 16 dynamic: 50 % > 40 %
  cv::Mat found(4, 4, CV_8UC1, cv::Scalar(0));
  found(cv::Rect(0, 0, 3, 2)) = 255;  // 6 of the 8 found, no false alarm
  cv::imwrite(tmp.file("gt/1.000000.png"), gtMask());  // 25 % dynamic: not occluded
  cv::imwrite(tmp.file("est/1.000000.png"), estMask());
  cv::imwrite(tmp.file("gt/2.000000.png"), occluded);
  cv::imwrite(tmp.file("est/2.000000.png"), found);
  const MaskIouResult result = evaluateMaskFolders(tmp.file("gt"), tmp.file("est"));
  ASSERT_EQ(result.num_frames, 2);
  EXPECT_EQ(result.num_occluded_frames, 1);
  EXPECT_NEAR(result.mean_static_iou_occluded, 8.0 / 10.0, 1e-12);
  EXPECT_NEAR(result.mean_static_iou, 0.5 * (8.0 / 14.0 + 8.0 / 10.0), 1e-12);
  // gt dynamic: 4 + 8 pixels; found: 2 (frame 1, columns 1) + 6.
  EXPECT_NEAR(result.dynamic_recall, 8.0 / 12.0, 1e-12);
  EXPECT_NEAR(result.mean_static_share, 0.5 * (10.0 / 16.0 + 10.0 / 16.0), 1e-12);
}

TEST(StaticIouErrors, MessagesNameTheFile) {
  TempDir tmp("eval_masks_err");
  fs::create_directories(tmp.file("gt"));
  fs::create_directories(tmp.file("est"));
  cv::imwrite(tmp.file("gt/1.000000.png"), gtMask());
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { evaluateMaskFolders(tmp.file("gt"), tmp.file("none")); }),
                       tmp.file("none") + ": mask folder does not exist");
  cv::imwrite(tmp.file("est/2.000000.png"), gtMask());
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { evaluateMaskFolders(tmp.file("gt"), tmp.file("est")); }),
                       "no mask file name matches");
  cv::imwrite(tmp.file("est/1.000000.png"), cv::Mat(4, 5, CV_8UC1, cv::Scalar(0)));
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { evaluateMaskFolders(tmp.file("gt"), tmp.file("est")); }),
                       tmp.file("est/1.000000.png") + ": size 5x4 differs from 4x4");
  cv::imwrite(tmp.file("est/1.000000.png"), cv::Mat(4, 4, CV_8UC3, cv::Scalar(0, 0, 0)));
  LTLO_EXPECT_CONTAINS(
      inputErrorOf([&] { evaluateMaskFolders(tmp.file("gt"), tmp.file("est")); }),
      tmp.file("est/1.000000.png") + ": expected an 8-bit 1-channel mask, found 3");
  cv::imwrite(tmp.file("est/frame.png"), gtMask());
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { evaluateMaskFolders(tmp.file("gt"), tmp.file("est")); }),
                       tmp.file("est/frame.png") + ": mask file name is not a timestamp: 'frame'");
}

}  // namespace
}  // namespace ltlo::eval
