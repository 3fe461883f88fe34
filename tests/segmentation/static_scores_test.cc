#include "ltlo/segmentation/static_scores.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "ltlo/core/assert.h"

namespace ltlo::segmentation {
namespace {

// 4x3 label image with K = 3: cluster 0 (4 px), 1 (3 px), 2 (2 px), no depth (3 px).
ClusterMap smallMap() {
  ClusterMap clusters;
  clusters.num_clusters = 3;
  clusters.labels = (cv::Mat_<int>(3, 4) << 0, 0, 1, 3,  //
                     0, 0, 1, 3,                         //
                     2, 2, 1, 3);
  clusters.pixel_counts = {4, 3, 2, 3};
  return clusters;
}

TEST(StaticScores, AllStaticGivesAnEmptyMaskAndFullRatio) {
  const ClusterMap clusters = smallMap();
  const StaticScores scores = StaticScores::allStatic(3);
  EXPECT_EQ(scores.numClusters(), 3);
  EXPECT_EQ(scores.values(), std::vector<double>({1.0, 1.0, 1.0, 1.0}));
  EXPECT_EQ(cv::countNonZero(scores.staticMask(clusters, 0.5)), 0);
  EXPECT_DOUBLE_EQ(scores.staticAreaRatio(clusters, 0.5), 1.0);
}

TEST(StaticScores, MaskAndRatioFollowTheThreshold) {
  const ClusterMap clusters = smallMap();
  StaticScores scores({0.9, 0.2, 0.5});
  EXPECT_DOUBLE_EQ(scores.gamma(3), 1.0);  // no-depth cluster is static
  const cv::Mat mask = scores.staticMask(clusters, 0.5);
  ASSERT_EQ(mask.type(), CV_8U);
  const cv::Mat expected = (cv::Mat_<uint8_t>(3, 4) << 0, 0, 255, 0,  //
                            0, 0, 255, 0,                             //
                            0, 0, 255, 0);
  EXPECT_EQ(cv::countNonZero(mask != expected), 0);
  EXPECT_DOUBLE_EQ(scores.staticAreaRatio(clusters, 0.5), 9.0 / 12.0);  // gamma = 0.5 is static
  EXPECT_DOUBLE_EQ(scores.staticAreaRatio(clusters, 0.6), 7.0 / 12.0);
  scores.setGamma(1, 0.7);
  EXPECT_DOUBLE_EQ(scores.staticAreaRatio(clusters, 0.6), 10.0 / 12.0);
  EXPECT_TRUE(scores.isStatic(1, 0.6));
  EXPECT_FALSE(scores.isStatic(2, 0.6));
}

TEST(StaticScores, ScoreOfPixelAndKeypoint) {
  const ClusterMap clusters = smallMap();
  const StaticScores scores({0.9, 0.2, 0.5});
  EXPECT_DOUBLE_EQ(scores.atPixel(clusters, 2, 0), 0.2);
  EXPECT_DOUBLE_EQ(scores.atPixel(clusters, 3, 2), 1.0);
  EXPECT_DOUBLE_EQ(scores.atPoint(clusters, Vec2(0.6, 1.6)), 0.5);  // nearest pixel (1, 2)
  EXPECT_DOUBLE_EQ(scores.atPoint(clusters, Vec2(0.4, 0.4)), 0.9);  // nearest pixel (0, 0)
}

TEST(StaticScores, RejectsScoresOutsideZeroOne) {
  EXPECT_THROW(StaticScores({0.5, 1.2}), AssertionError);
  StaticScores scores({0.5});
  EXPECT_THROW(scores.setGamma(0, -0.1), AssertionError);
  EXPECT_THROW(scores.setGamma(1, 0.5), AssertionError);  // the no-depth score stays 1
}

}  // namespace
}  // namespace ltlo::segmentation
