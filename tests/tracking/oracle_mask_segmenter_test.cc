// The --oracle-masks ablation's segmenter: ground-truth masks become a three-cluster segmentation
// (static with depth, dynamic, static without depth) with the fields local mapping needs, and a
// frame without a mask is bad input naming the frame.
#include "ltlo/tracking/oracle_mask_segmenter.h"

#include <gtest/gtest.h>

#include <string>

#include "ltlo/core/errors.h"

namespace ltlo::tracking {
namespace {

constexpr int kWidth = 64;
constexpr int kHeight = 48;

map::Frame frameWithKeypoints(const std::vector<Vec2>& positions) {
  features::OrbFeatures features;
  for (const Vec2& p : positions) {
    features::Keypoint kp;
    kp.x_px = static_cast<float>(p.x());
    kp.y_px = static_cast<float>(p.y());
    features.keypoints.push_back(kp);
    features.descriptors.emplace_back();
  }
  const PinholeCamera camera(50.0, 50.0, 31.5, 23.5, kWidth, kHeight);
  std::vector<float> depths(positions.size(), 2.0f);
  return map::Frame(0.0, camera, SE3(), std::move(features), std::move(depths), {1.0f});
}

TEST(OracleMaskSegmenter, GroundTruthMaskBecomesStaticDynamicAndNoDepthClusters) {
  io::RgbdImuFrame input;
  input.color_bgr = cv::Mat(kHeight, kWidth, CV_8UC3, cv::Scalar(0, 0, 0));
  input.depth_m = cv::Mat(kHeight, kWidth, CV_32F, cv::Scalar(2.0f));
  input.mask = cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
  input.mask(cv::Rect(32, 0, 32, kHeight)).setTo(255);                   // right half dynamic
  input.depth_m(cv::Rect(0, 0, 16, 8)).setTo(0.0f);                      // a static hole
  input.depth_m(cv::Rect(48, 0, 16, 8)).setTo(0.0f);                     // a dynamic hole
  map::Frame frame = frameWithKeypoints({{10.0, 20.0}, {40.0, 20.0}, {4.0, 2.0}, {50.0, 2.0}});

  OracleMaskSegmenter segmenter(0.5);
  segmenter.begin(input);
  const SegmentationOutcome outcome = segmenter.segment(frame, MotionPrior());
  const map::ClusterSegmentation& seg = frame.segmentation();
  seg.validate();
  ASSERT_EQ(seg.numClusters(), 3);
  EXPECT_EQ(seg.scale, OracleMaskSegmenter::kLabelScale);
  EXPECT_EQ(seg.labels.cols, kWidth / 2);
  EXPECT_EQ(seg.gamma, (std::vector<double>{1.0, 0.0, 1.0}));
  EXPECT_EQ(seg.noDepthCluster(), OracleMaskSegmenter::kNoDepthCluster);
  // Label pixels: 32x24, the right half (16x24 = 384) dynamic with or without depth, the static
  // hole 8x4 = 32, the rest static with depth.
  EXPECT_EQ(seg.pixel_counts[OracleMaskSegmenter::kDynamicCluster], 384);
  EXPECT_EQ(seg.pixel_counts[OracleMaskSegmenter::kNoDepthCluster], 32);
  EXPECT_EQ(seg.pixel_counts[OracleMaskSegmenter::kStaticCluster], 384 - 32);
  EXPECT_EQ(seg.neighbours, (std::vector<std::pair<int, int>>{{0, 1}}));
  ASSERT_EQ(seg.depth_mm.type(), CV_16U);
  EXPECT_EQ(seg.depth_mm.cols, kWidth / 4);
  EXPECT_EQ(seg.depth_mm.at<std::uint16_t>(10, 2), 2000);
  EXPECT_NEAR(seg.depthAt_m(20.0, 30.0), 2.0, 1e-9);
  // Static area: the dynamic cluster holds the dynamic pixels without depth too (gamma 0 on every
  // dynamic pixel), so they count as dynamic area: 352 static of 352 + 384.
  EXPECT_NEAR(seg.staticAreaRatio(0.5), 352.0 / (352.0 + 384.0), 1e-12);
  EXPECT_NEAR(outcome.dynamic_share, 384.0 / (384.0 + 352.0), 1e-12);
  EXPECT_FALSE(outcome.state_refined);
  // Keypoints: static with depth, dynamic, static in the hole (gamma 1), dynamic in its hole.
  EXPECT_TRUE(frame.isStatic(0));
  EXPECT_FALSE(frame.isStatic(1));
  EXPECT_TRUE(frame.isStatic(2));
  EXPECT_FALSE(frame.isStatic(3));
  EXPECT_EQ(frame.staticKeypoints(), (std::vector<int>{0, 2}));
}

TEST(OracleMaskSegmenter, FrameWithoutMaskIsBadInput) {
  io::RgbdImuFrame input;
  input.color_bgr = cv::Mat(kHeight, kWidth, CV_8UC3, cv::Scalar(0, 0, 0));
  input.depth_m = cv::Mat(kHeight, kWidth, CV_32F, cv::Scalar(2.0f));
  input.color_path = "seq/rgb/1.500000.png";
  input.t_s = 1.5;
  map::Frame frame = frameWithKeypoints({{10.0, 20.0}});
  OracleMaskSegmenter segmenter(0.5);
  segmenter.begin(input);
  try {
    segmenter.segment(frame, MotionPrior());
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("seq/rgb/1.500000.png"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--oracle-masks: no ground-truth mask"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ltlo::tracking
