// Covisibility consistency of loop candidates over consecutive queries (no map needed).
#include <gtest/gtest.h>

#include "ltlo/loop/loop_detector.h"

namespace ltlo::loop {
namespace {

using map::KeyFrameId;

CandidateGroup group(std::uint64_t candidate, std::vector<std::uint64_t> members) {
  CandidateGroup g;
  g.candidate = KeyFrameId(candidate);
  for (const std::uint64_t m : members) g.members.push_back(KeyFrameId(m));
  return g;
}

TEST(ConsistencyChecker, AcceptsACandidateSeenThreeTimes) {
  ConsistencyChecker checker(3);
  // The same place, recognised through neighbouring keyframes of one covisibility group.
  EXPECT_TRUE(checker.update({group(10, {9, 11, 12})}).empty());
  EXPECT_EQ(checker.maxCount(), 1);
  EXPECT_TRUE(checker.update({group(11, {10, 12, 13})}).empty());
  EXPECT_EQ(checker.maxCount(), 2);
  const std::vector<KeyFrameId> accepted = checker.update({group(12, {11, 13, 14})});
  ASSERT_EQ(accepted.size(), 1u);
  EXPECT_EQ(accepted[0], KeyFrameId(12));
}

TEST(ConsistencyChecker, RejectsAOneOff) {
  ConsistencyChecker checker(3);
  EXPECT_TRUE(checker.update({group(10, {9, 11})}).empty());
  // A different place (no shared keyframe) restarts the count, then the first one reappears.
  EXPECT_TRUE(checker.update({group(50, {49, 51})}).empty());
  EXPECT_EQ(checker.maxCount(), 1);
  EXPECT_TRUE(checker.update({group(10, {9, 11})}).empty());
  EXPECT_EQ(checker.maxCount(), 1);
  // A one-off among consistent ones is not accepted; the consistent one is.
  EXPECT_TRUE(checker.update({group(10, {9, 11}), group(80, {81})}).empty());
  const std::vector<KeyFrameId> accepted = checker.update({group(11, {10}), group(90, {91})});
  ASSERT_EQ(accepted.size(), 1u);
  EXPECT_EQ(accepted[0], KeyFrameId(11));
}

TEST(ConsistencyChecker, ResetForgetsTheHistory) {
  ConsistencyChecker checker(3);
  checker.update({group(10, {11})});
  checker.update({group(10, {11})});
  checker.reset();
  EXPECT_TRUE(checker.update({group(10, {11})}).empty());
  EXPECT_EQ(checker.maxCount(), 1);
}

}  // namespace
}  // namespace ltlo::loop
