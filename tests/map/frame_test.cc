// Frame: depth lookup and back-projection, the grid, the segmentation seam and the static-only BoW.
#include <algorithm>
#include <cmath>
#include <gtest/gtest.h>

#include "bow/vocabulary.h"
#include "ltlo/core/assert.h"
#include "ltlo/map/frame.h"
#include "ltlo/map/keyframe.h"
#include "map_test_util.h"

namespace ltlo::map {
namespace {

Frame gridFrame() {
  // Keypoints on a 10 px lattice: (10 i, 10 j) for i < 64, j < 48, octave = (i + j) % 4.
  features::OrbFeatures features;
  std::vector<float> depths;
  for (int j = 0; j < 48; ++j) {
    for (int i = 0; i < 64; ++i) {
      features::Keypoint kp;
      kp.x_px = 10.0f * i;
      kp.y_px = 10.0f * j;
      kp.octave = (i + j) % 4;
      features.keypoints.push_back(kp);
      features.descriptors.push_back({static_cast<std::uint64_t>(i), static_cast<std::uint64_t>(j), 0, 0});
      depths.push_back(i % 2 == 0 ? 2.0f : 0.0f);
    }
  }
  return Frame(0.5, test::vgaCamera(), SE3(), std::move(features), std::move(depths), test::scaleFactors());
}

TEST(Frame, DepthAtKeypointsAndBackProjection) {
  cv::Mat depth(480, 640, CV_32F, cv::Scalar(0.0f));
  depth.at<float>(100, 200) = 2.5f;
  depth.at<float>(101, 200) = std::numeric_limits<float>::quiet_NaN();
  std::vector<features::Keypoint> kps(4);
  kps[0].x_px = 200.3f, kps[0].y_px = 99.6f;   // rounds to (200, 100)
  kps[1].x_px = 200.0f, kps[1].y_px = 101.0f;  // NaN
  kps[2].x_px = 10.0f, kps[2].y_px = 10.0f;    // zero
  kps[3].x_px = 700.0f, kps[3].y_px = 10.0f;   // outside
  EXPECT_EQ(depthsAtKeypoints(depth, kps), (std::vector<float>{2.5f, 0.0f, 0.0f, 0.0f}));

  const Frame frame = gridFrame();
  const int i = 3 * 64 + 4;  // (40, 30), depth 2
  const Vec3 expected((40.0 - 319.5) / 525.0 * 2.0, (30.0 - 239.5) / 525.0 * 2.0, 2.0);
  EXPECT_LT((frame.p_c(i) - expected).norm(), 1e-6);
  EXPECT_EQ(frame.p_c(i + 1), Vec3::Zero());  // no depth
  EXPECT_FALSE(frame.hasPose());
}

TEST(Frame, FeaturesInAreaMatchesBruteForce) {
  const Frame frame = gridFrame();
  const std::vector<int> found = frame.featuresInArea(105.0f, 52.0f, 21.0f, 1, 2);
  std::vector<int> expected;
  for (int k = 0; k < frame.numKeypoints(); ++k) {
    const features::Keypoint& kp = frame.keypoints()[static_cast<std::size_t>(k)];
    if (std::abs(kp.x_px - 105.0f) <= 21.0f && std::abs(kp.y_px - 52.0f) <= 21.0f && kp.octave >= 1 && kp.octave <= 2) {
      expected.push_back(k);
    }
  }
  EXPECT_EQ(found, expected);
  EXPECT_EQ(expected.size(), 8u);  // x in {90..120} x y in {40..70}: 16 keypoints, half with octave 1 or 2
  // Into a reused buffer: cleared first, the same answer.
  std::vector<int> reused = {7, 7, 7};
  frame.featuresInArea(105.0f, 52.0f, 21.0f, 1, 2, &reused);
  EXPECT_EQ(reused, expected);
  frame.featuresInArea(2000.0f, 2000.0f, 5.0f, 0, -1, &reused);
  EXPECT_TRUE(reused.empty());
}

TEST(Frame, StaticFilterFollowsClusterScores) {
  Frame frame = gridFrame();
  EXPECT_EQ(frame.staticKeypoints().size(), static_cast<std::size_t>(frame.numKeypoints()));  // trivial seam
  // Three clusters: left half 0, right half 1, top rows 2 ("no depth"); gamma = {1, 0.2, 1}.
  ClusterSegmentation seg;
  seg.labels = cv::Mat(480, 640, CV_8U, cv::Scalar(0));
  seg.labels(cv::Rect(320, 0, 320, 480)).setTo(1);
  seg.labels(cv::Rect(0, 0, 640, 120)).setTo(2);
  seg.gamma = {1.0, 0.2, 1.0};
  frame.setSegmentation(seg, 0.5);
  const int left = 20 * 64 + 10, right = 20 * 64 + 40, top = 5 * 64 + 40;  // (100, 200), (400, 200), (400, 50)
  EXPECT_EQ(frame.clusterOf(left), 0);
  EXPECT_EQ(frame.clusterOf(right), 1);
  EXPECT_EQ(frame.clusterOf(top), 2);
  EXPECT_TRUE(frame.isStatic(left));
  EXPECT_FALSE(frame.isStatic(right));
  EXPECT_TRUE(frame.isStatic(top));
  // Cluster 2 (the last) is "no depth" and counts in neither part of the static area: of the
  // 640 x 360 pixels with depth, the right half is dynamic.
  EXPECT_DOUBLE_EQ(seg.staticAreaRatio(0.5), 0.5);
  EXPECT_DOUBLE_EQ(seg.staticAreaRatio(0.1), 1.0);

  // The keyframe copies labels and scores and recomputes the ratio when Gamma changes.
  frame.setPose_T_w_b(SE3());
  KeyFrame kf(KeyFrameId(0), MapId(0), frame);
  EXPECT_DOUBLE_EQ(kf.staticAreaRatio(), 0.5);
  EXPECT_FALSE(kf.isStatic(right));
  kf.setGamma({1.0, 0.9, 0.0});
  EXPECT_TRUE(kf.isStatic(right));
  EXPECT_FALSE(kf.isStatic(top));
  EXPECT_DOUBLE_EQ(kf.staticAreaRatio(), 1.0);
  kf.setGamma({0.2, 0.9, 1.0});
  EXPECT_DOUBLE_EQ(kf.staticAreaRatio(), 0.5);
  kf.setGamma({1.0, 0.9, 0.0});
  std::vector<int> expected_static;
  for (int i = 0; i < kf.numKeypoints(); ++i) {
    if (kf.clusterOf(i) != 2) expected_static.push_back(i);
  }
  EXPECT_EQ(kf.staticKeypoints(), expected_static);
  EXPECT_EQ(expected_static.size(), 64u * 36u);  // rows 12..47 of the lattice lie below y = 120
  EXPECT_EQ(kf.segmentation().gamma, (std::vector<double>{1.0, 0.9, 0.0}));
  EXPECT_EQ(cv::countNonZero(kf.segmentation().labels != frame.segmentation().labels), 0);

  seg.gamma = {1.0, 1.5, 1.0};
  EXPECT_THROW(frame.setSegmentation(seg), AssertionError);
  seg.gamma = {1.0, 1.0};
  EXPECT_THROW(frame.setSegmentation(seg), AssertionError);  // label 2 has no score
}

TEST(ClusterSegmentation, ReducedResolutionLookupsMaskAndMemory) {
  // QVGA labels and QQVGA depth for a VGA image: a dynamic box over input columns [200, 400).
  ClusterSegmentation seg;
  seg.scale = 2;
  seg.labels = cv::Mat(240, 320, CV_8U, cv::Scalar(0));
  seg.labels(cv::Rect(100, 0, 100, 240)).setTo(1);
  seg.labels(cv::Rect(0, 0, 320, 10)).setTo(2);  // no depth in the top 20 input rows
  seg.gamma = {1.0, 0.0, 1.0};
  seg.pixel_counts = {220 * 230, 100 * 230, 320 * 10};
  seg.neighbours = {{0, 1}};
  seg.depth_scale = 4;
  seg.depth_mm = cv::Mat(120, 160, CV_16U, cv::Scalar(2000));
  seg.depth_mm.at<std::uint16_t>(50, 75) = 1234;  // input pixels x 300..303, y 200..203
  seg.validate();
  EXPECT_EQ(seg.clusterAt(199.4f, 100.0f), 0);
  EXPECT_EQ(seg.clusterAt(199.6f, 100.0f), 1);  // rounds to input pixel 200, label column 100
  EXPECT_EQ(seg.clusterAt(399.0f, 100.0f), 1);
  EXPECT_EQ(seg.clusterAt(400.0f, 100.0f), 0);
  EXPECT_EQ(seg.clusterAt(10.0f, 19.0f), 2);
  EXPECT_EQ(seg.clusterAt(10.0f, 20.0f), 0);
  EXPECT_EQ(seg.clusterAt(-5.0f, 1000.0f), 0);  // clamped
  EXPECT_EQ(seg.noDepthCluster(), 2);
  EXPECT_DOUBLE_EQ(seg.depthAt_m(301.0, 202.0), 1.234);
  EXPECT_DOUBLE_EQ(seg.depthAt_m(304.0, 202.0), 2.0);
  EXPECT_DOUBLE_EQ(seg.depthAt_m(700.0, 202.0), 0.0);
  EXPECT_DOUBLE_EQ(seg.staticAreaRatio(0.5), 220.0 / 320.0);
  const cv::Mat mask = seg.dynamicMask(0.5);
  ASSERT_EQ(mask.size(), cv::Size(320, 240));
  EXPECT_EQ(cv::countNonZero(mask), 100 * 230);  // the no-depth rows are static (gamma 1)
  EXPECT_EQ(seg.memoryBytes(), 320u * 240u + 160u * 120u * 2u + 3u * sizeof(double) + 3u * sizeof(int) +
                                   sizeof(std::pair<int, int>));
  EXPECT_LT(seg.memoryBytes(), 200000u);  // the per-keyframe budget of the segmentation issue
  // Counted on demand when the counts are absent: the same ratio.
  seg.pixel_counts.clear();
  EXPECT_DOUBLE_EQ(seg.staticAreaRatio(0.5), 220.0 / 320.0);

  // The inline rounding is std::lround's (half away from zero) everywhere a lookup can land,
  // halves, negatives and the far edges included.
  seg.depth_mm = cv::Mat(120, 160, CV_16U);
  cv::randu(seg.depth_mm, 0, 5000);
  auto clusterByLround = [&](float x, float y) {
    const int col = std::clamp(static_cast<int>(std::lround(x)) / seg.scale, 0, seg.labels.cols - 1);
    const int row = std::clamp(static_cast<int>(std::lround(y)) / seg.scale, 0, seg.labels.rows - 1);
    return static_cast<int>(seg.labels.at<std::uint8_t>(row, col));
  };
  auto depthByLround = [&](double x, double y) {
    const long xi = std::lround(x), yi = std::lround(y);
    if (xi < 0 || yi < 0 || xi / seg.depth_scale >= seg.depth_mm.cols || yi / seg.depth_scale >= seg.depth_mm.rows) {
      return 0.0;
    }
    return 1e-3 * seg.depth_mm.at<std::uint16_t>(static_cast<int>(yi / seg.depth_scale), static_cast<int>(xi / seg.depth_scale));
  };
  int compared = 0;
  for (double x = -3.0; x <= 643.0; x += 0.25) {
    for (const double y : {-1.5, -0.5, -0.25, 0.0, 0.5, 19.5, 101.75, 478.5, 479.5, 480.0}) {
      for (const double dx : {0.0, 1e-4, -1e-4}) {
        const double xx = x + dx;
        ASSERT_EQ(seg.clusterAt(static_cast<float>(xx), static_cast<float>(y)),
                  clusterByLround(static_cast<float>(xx), static_cast<float>(y))) << xx << ", " << y;
        ASSERT_EQ(seg.depthAt_m(xx, y), depthByLround(xx, y)) << xx << ", " << y;
        ++compared;
      }
    }
  }
  EXPECT_EQ(compared, 2585 * 10 * 3);

  const ClusterSegmentation trivial = ClusterSegmentation::allStatic();
  EXPECT_EQ(trivial.clusterAt(100.0f, 100.0f), 0);
  EXPECT_EQ(trivial.noDepthCluster(), -1);
  EXPECT_DOUBLE_EQ(trivial.staticAreaRatio(0.5), 1.0);
  EXPECT_EQ(cv::countNonZero(trivial.dynamicMask(0.5, 48, 64)), 0);

  seg.labels.at<std::uint8_t>(0, 0) = 3;  // a label without a score
  EXPECT_THROW(seg.validate(), AssertionError);
}

TEST(Frame, BowUsesStaticKeypointsOnlyAndIndexesKeypoints) {
  // A tiny vocabulary on random descriptors; the dynamic keypoints must not reach the BoW.
  std::mt19937 rng(11);
  Frame frame = test::randomFrame(rng, 0.0, SE3(), 300);
  const bow::Vocabulary vocabulary =
      bow::Vocabulary::train({frame.descriptors()}, bow::TrainOptions{4, 3, 5, 1, 1, 0, {}});
  ClusterSegmentation seg;
  seg.labels = cv::Mat(240, 320, CV_8U, cv::Scalar(0));
  seg.scale = 2;
  seg.labels(cv::Rect(0, 0, 320, 120)).setTo(1);  // top half dynamic
  seg.gamma = {1.0, 0.0};
  frame.setSegmentation(seg);
  frame.computeBow(vocabulary, 1);
  const std::vector<int> statics = frame.staticKeypoints();
  ASSERT_GT(statics.size(), 100u);
  ASSERT_LT(statics.size(), 200u);
  std::size_t indexed = 0;
  for (const auto& [node, indices] : frame.featureVector()) {
    for (std::uint32_t i : indices) {
      EXPECT_TRUE(frame.isStatic(static_cast<int>(i))) << "keypoint " << i;
      ++indexed;
    }
  }
  EXPECT_EQ(indexed, statics.size());
  std::vector<features::Descriptor> static_descriptors;
  for (int i : statics) static_descriptors.push_back(frame.descriptors()[static_cast<std::size_t>(i)]);
  bow::BowVector expected;
  vocabulary.transform(static_descriptors, &expected);
  EXPECT_EQ(frame.bowVector().entries, expected.entries);
}

}  // namespace
}  // namespace ltlo::map
