#include "ltlo/features/matching.h"

#include <random>

#include <gtest/gtest.h>

namespace ltlo::features {
namespace {

TEST(Hamming, CountsDifferingBits) {
  const Descriptor zero{0, 0, 0, 0};
  const Descriptor ones{~0ULL, ~0ULL, ~0ULL, ~0ULL};
  EXPECT_EQ(hammingDistance(zero, zero), 0);
  EXPECT_EQ(hammingDistance(zero, ones), 256);
  EXPECT_EQ(hammingDistance(zero, Descriptor{1, 3, 0, 1ULL << 63}), 4);
}

TEST(RatioTest, AcceptsOnlyClearWinners) {
  EXPECT_TRUE(passesRatioTest(20, 40, 0.7));
  EXPECT_FALSE(passesRatioTest(30, 40, 0.7));
  EXPECT_FALSE(passesRatioTest(28, 40, 0.7));  // 28 is not < 0.7 * 40
}

TEST(RotationHistogram, KeepsTheDominantRotation) {
  RotationHistogram histogram;
  // 40 matches rotated by ~30 degrees (bins 2 and 3), 12 scattered outliers one per bin.
  for (int i = 0; i < 40; ++i) histogram.add(10.0f, 10.0f + 30.0f + static_cast<float>(i % 5) - 2.0f, i);
  for (int i = 0; i < 12; ++i) histogram.add(0.0f, 100.0f + 20.0f * i, 40 + i);
  const std::vector<int> kept = histogram.consistent();
  int inliers = 0;
  for (int index : kept) inliers += index < 40;
  EXPECT_EQ(inliers, 40);
  // The third bin holds one outlier (1 < 10% of the top bin), so at most the two inlier bins remain.
  EXPECT_EQ(kept.size(), 40u);
}

TEST(RotationHistogram, HandlesWrapAround) {
  RotationHistogram histogram;
  for (int i = 0; i < 20; ++i) histogram.add(350.0f, 5.0f, i);  // +15 degrees through 0
  EXPECT_EQ(histogram.consistent().size(), 20u);
}

TEST(KeypointGrid, CandidatesEqualBruteForce) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> x(0.0f, 640.0f), y(0.0f, 480.0f);
  std::vector<Keypoint> keypoints(3000);
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    keypoints[i].x_px = x(rng);
    keypoints[i].y_px = y(rng);
    keypoints[i].octave = static_cast<int>(i % 8);
  }
  const KeypointGrid grid(keypoints, 640, 480);
  for (int q = 0; q < 200; ++q) {
    const float qx = x(rng) * 1.1f - 30.0f;  // some queries near or outside the border
    const float qy = y(rng) * 1.1f - 20.0f;
    const float radius = 3.0f + static_cast<float>(q % 40);
    const int min_octave = q % 3;
    const int max_octave = q % 2 ? -1 : 5;
    std::vector<int> expected;
    for (int i = 0; i < static_cast<int>(keypoints.size()); ++i) {
      const Keypoint& kp = keypoints[i];
      if (kp.octave < min_octave || (max_octave >= 0 && kp.octave > max_octave)) continue;
      if (std::abs(kp.x_px - qx) <= radius && std::abs(kp.y_px - qy) <= radius) expected.push_back(i);
    }
    EXPECT_EQ(grid.candidates(qx, qy, radius, min_octave, max_octave), expected) << "query " << q;
  }
}

TEST(FindNearest, ReturnsBestAndSecondBest) {
  const std::vector<Descriptor> descriptors{{0, 0, 0, 0b111}, {0, 0, 0, 0b1}, {0, 0, 0, 0b11}};
  const NearestResult r = findNearest(Descriptor{0, 0, 0, 0}, descriptors, {0, 1, 2});
  EXPECT_EQ(r.index, 1);
  EXPECT_EQ(r.distance, 1);
  EXPECT_EQ(r.second_distance, 2);
  EXPECT_EQ(findNearest(Descriptor{}, descriptors, {}).index, -1);
}

TEST(MatchByBow, MatchesOnlyWithinSharedNodes) {
  std::mt19937_64 rng(4);
  OrbFeatures a, b;
  for (int i = 0; i < 6; ++i) {
    a.descriptors.push_back({rng(), rng(), rng(), rng()});
    a.keypoints.push_back(Keypoint{});
  }
  // b holds exact copies of a's features in reverse order.
  for (int i = 5; i >= 0; --i) {
    b.descriptors.push_back(a.descriptors[i]);
    b.keypoints.push_back(Keypoint{});
  }
  // a's features 0..2 share node 7 with their copies; feature 3's copy sits under another node.
  const NodeFeatures nodes_a{{7, {0, 1, 2}}, {9, {3, 4, 5}}};
  const NodeFeatures nodes_b{{7, {5, 4, 3}}, {9, {1, 0}}, {11, {2}}};
  const std::vector<Match> matches = matchByBow(nodes_a, a, nodes_b, b, GuidedMatchOptions{});
  ASSERT_EQ(matches.size(), 5u);
  for (const Match& m : matches) {
    EXPECT_EQ(m.train, 5 - m.query);
    EXPECT_EQ(m.distance, 0);
    EXPECT_NE(m.query, 3);
  }
}

}  // namespace
}  // namespace ltlo::features
