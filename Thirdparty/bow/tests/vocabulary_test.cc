#include "bow/vocabulary.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "test_data.h"

namespace bow {
namespace {

TrainOptions smallOptions(int threads) {
  TrainOptions options;
  options.branching = 6;
  options.depth = 3;
  options.num_threads = threads;
  options.seed = 42;
  return options;
}

class VocabularyTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::mt19937_64 rng(3);
    prototypes_ = test::makePrototypes(300, rng);
    images_ = test::makeImages(prototypes_, 60, 200, 12, rng);
    vocabulary_ = Vocabulary::train(images_, smallOptions(2));
  }
  std::vector<Descriptor> prototypes_;
  std::vector<std::vector<Descriptor>> images_;
  Vocabulary vocabulary_;
};

TEST_F(VocabularyTest, TreeHasExpectedShape) {
  EXPECT_EQ(vocabulary_.branching(), 6);
  EXPECT_EQ(vocabulary_.depth(), 3);
  // 6^3 = 216 leaves at most; 12,000 descriptors around 300 prototypes fill nearly all of them.
  EXPECT_LE(vocabulary_.numWords(), 216u);
  EXPECT_GE(vocabulary_.numWords(), 180u);
  EXPECT_LE(vocabulary_.numNodes(), 1u + 6u + 36u + 216u);
}

TEST_F(VocabularyTest, TrainingIsDeterministicAndThreadCountIndependent) {
  EXPECT_TRUE(Vocabulary::train(images_, smallOptions(2)) == vocabulary_);
  EXPECT_TRUE(Vocabulary::train(images_, smallOptions(1)) == vocabulary_);
  TrainOptions other = smallOptions(2);
  other.seed = 43;
  EXPECT_FALSE(Vocabulary::train(images_, other) == vocabulary_);
}

TEST_F(VocabularyTest, NoisyCopiesOfAPrototypeShareItsWord) {
  std::mt19937_64 rng(11);
  int same = 0;
  int total = 0;
  for (const Descriptor& p : prototypes_) {
    const WordId w = vocabulary_.wordOf(p);
    for (int i = 0; i < 5; ++i) {
      same += vocabulary_.wordOf(test::flipBits(p, 8, rng)) == w;
      ++total;
    }
  }
  EXPECT_GT(static_cast<double>(same) / total, 0.9) << same << " / " << total;
}

TEST_F(VocabularyTest, TransformGivesSortedL1NormalisedVectorAndDirectIndex) {
  BowVector v;
  FeatureVector fv;
  vocabulary_.transform(images_[5], &v, &fv, 2);
  ASSERT_FALSE(v.empty());
  double sum = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    sum += v.entries[i].second;
    EXPECT_GT(v.entries[i].second, 0.0f);
    if (i > 0) {
      EXPECT_LT(v.entries[i - 1].first, v.entries[i].first);
    }
  }
  EXPECT_NEAR(sum, 1.0, 1e-5);
  EXPECT_NEAR(l1Score(v, v), 1.0, 1e-5);
  std::size_t indexed = 0;
  for (const auto& [node, features] : fv) indexed += features.size();
  EXPECT_EQ(indexed, images_[5].size());
  EXPECT_LE(fv.size(), 36u);  // depth-2 nodes of a k = 6 tree

  BowVector other;
  vocabulary_.transform(images_[40], &other);
  EXPECT_LT(l1Score(v, other), 0.5);  // different prototype subsets
}

TEST_F(VocabularyTest, IdfIsLogOfImageFrequency) {
  // Every weight is ln(N / n_w) with 1 <= n_w <= N = 60.
  for (WordId w = 0; w < vocabulary_.numWords(); ++w) {
    EXPECT_GE(vocabulary_.wordWeight(w), 0.0f);
    EXPECT_LE(vocabulary_.wordWeight(w), std::log(60.0f) + 1e-5f);
  }
}

TEST_F(VocabularyTest, BinaryRoundTripGivesIdenticalTransforms) {
  const std::string path = ::testing::TempDir() + "bow_roundtrip.bin";
  vocabulary_.save(path);
  const Vocabulary loaded = Vocabulary::load(path);
  EXPECT_TRUE(loaded == vocabulary_);
  for (int i = 0; i < 10; ++i) {
    BowVector a, b;
    FeatureVector fa, fb;
    vocabulary_.transform(images_[i], &a, &fa, 2);
    loaded.transform(images_[i], &b, &fb, 2);
    EXPECT_EQ(a.entries, b.entries);
    EXPECT_EQ(fa, fb);
  }
  std::remove(path.c_str());
}

TEST_F(VocabularyTest, TextExportHasOneLinePerNode) {
  const std::string path = ::testing::TempDir() + "bow_export.txt";
  vocabulary_.saveText(path);
  std::ifstream in(path);
  std::string line;
  std::size_t lines = 0;
  while (std::getline(in, line)) ++lines;
  EXPECT_EQ(lines, vocabulary_.numNodes() + 2);  // two header lines
  std::remove(path.c_str());
}

TEST(VocabularyFile, TruncatedFileIsRejectedWithItsPath) {
  const std::string path = ::testing::TempDir() + "bow_truncated.bin";
  {
    std::ofstream out(path, std::ios::binary);
    out << "LTLOBOW1" << std::string(12, '\x01');
  }
  try {
    Vocabulary::load(path);
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
}

TEST(VocabularyTrain, IdenticalDescriptorsGiveOneWordWithoutWeight) {
  const std::vector<std::vector<Descriptor>> images(3, std::vector<Descriptor>(50, Descriptor{1, 2, 3, 4}));
  const Vocabulary vocabulary = Vocabulary::train(images, TrainOptions{});
  ASSERT_EQ(vocabulary.numWords(), 1u);
  EXPECT_EQ(vocabulary.wordWeight(0), 0.0f);  // in every image: idf = ln(3 / 3)
  BowVector v;
  vocabulary.transform(images[0], &v);
  EXPECT_TRUE(v.empty());  // zero-weight words carry no information and are dropped
}

TEST(VocabularyTrain, RejectsBadOptions) {
  std::mt19937_64 rng(1);
  const std::vector<std::vector<Descriptor>> images{{test::randomDescriptor(rng)}};
  TrainOptions options;
  options.branching = 1;
  EXPECT_THROW(Vocabulary::train(images, options), std::invalid_argument);
  EXPECT_THROW(Vocabulary::train({}, TrainOptions{}), std::invalid_argument);
}

}  // namespace
}  // namespace bow
