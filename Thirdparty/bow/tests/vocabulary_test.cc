#include "bow/vocabulary.h"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

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

TEST_F(VocabularyTest, ChecksumFollowsEqualityAndSurvivesTheFile) {
  const std::string path = ::testing::TempDir() + "/bow_checksum.bin";
  vocabulary_.save(path);
  EXPECT_EQ(Vocabulary::load(path).checksum(), vocabulary_.checksum());
  EXPECT_EQ(Vocabulary::train(images_, smallOptions(1)).checksum(), vocabulary_.checksum());
  TrainOptions other = smallOptions(2);
  other.seed = 43;
  EXPECT_NE(Vocabulary::train(images_, other).checksum(), vocabulary_.checksum());
  EXPECT_NE(Vocabulary().checksum(), vocabulary_.checksum());
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

// A hand-made vocabulary file: header (k, L, node count) and nodes (child count, weight).
struct FileNode {
  std::uint16_t children;
  float weight;
};
std::string vocabularyBytes(std::uint32_t k, std::uint32_t L, const std::vector<FileNode>& nodes) {
  std::string bytes = "LTLOBOW1";
  const std::uint32_t header[3] = {k, L, static_cast<std::uint32_t>(nodes.size())};
  bytes.append(reinterpret_cast<const char*>(header), sizeof(header));
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    bytes.append(reinterpret_cast<const char*>(&nodes[i].children), 2);
    bytes.append(reinterpret_cast<const char*>(&nodes[i].weight), 4);
    const Descriptor centre{i, 0, 0, 0};
    bytes.append(reinterpret_cast<const char*>(centre.data()), 32);
  }
  return bytes;
}

/// what() of the FileError the bytes give, with its offset and value checked.
std::string fileErrorOf(const std::string& bytes, long long offset, const std::string& value) {
  try {
    Vocabulary::fromBytes(bytes.data(), bytes.size(), "voc.bin");
  } catch (const FileError& e) {
    EXPECT_EQ(e.path(), "voc.bin");
    EXPECT_EQ(e.offset(), offset) << e.what();
    EXPECT_EQ(e.value(), value) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "expected a FileError";
  return "";
}

TEST(VocabularyFile, SmallestValidTreeLoadsAndTransforms) {
  // Root with two leaves: two words.
  const std::string bytes = vocabularyBytes(2, 1, {{2, 0.0f}, {0, 0.5f}, {0, 1.5f}});
  const Vocabulary vocabulary = Vocabulary::fromBytes(bytes.data(), bytes.size(), "voc.bin");
  EXPECT_EQ(vocabulary.numWords(), 2u);
  BowVector v;
  vocabulary.transform({Descriptor{2, 0, 0, 0}, Descriptor{2, 0, 0, 0}}, &v);  // nearest to node 2
  ASSERT_EQ(v.size(), 1u);
  EXPECT_EQ(v.entries[0].first, 1u);
  EXPECT_FLOAT_EQ(vocabulary.wordWeight(1), 1.5f);
}

TEST(VocabularyFile, EveryMalformedFieldIsNamedWithItsOffsetAndValue) {
  const std::vector<FileNode> good = {{2, 0.0f}, {0, 0.5f}, {0, 1.5f}};
  EXPECT_NE(fileErrorOf("LTLOBOW1\x01", 0, "need 20").find("voc.bin: byte 0: too short"), std::string::npos);
  EXPECT_NE(fileErrorOf("GIF89a" + std::string(30, '\0'), 0, "magic 'GIF89a\\x00\\x00'")
                .find("not an LTLOBOW1 vocabulary file"),
            std::string::npos);
  EXPECT_NE(fileErrorOf(vocabularyBytes(1, 1, good), 8, "1").find("voc.bin: byte 8: branching factor k"),
            std::string::npos);
  EXPECT_NE(fileErrorOf(vocabularyBytes(2, 0, good), 12, "0").find("depth L outside [1, 10]"), std::string::npos);
  std::string truncated = vocabularyBytes(2, 1, good);
  truncated.pop_back();
  EXPECT_NE(fileErrorOf(truncated, 16, "3").find("node count does not match the file size 133 bytes"),
            std::string::npos);
  // Root with 0 children: node 1 is nobody's child (a cycle or an orphan otherwise).
  EXPECT_NE(fileErrorOf(vocabularyBytes(2, 1, {{0, 0.0f}, {1, 0.5f}, {0, 1.5f}}), 20 + 38, "")
                .find("node 1 is no node's child"),
            std::string::npos);
  EXPECT_NE(fileErrorOf(vocabularyBytes(2, 1, {{3, 0.0f}, {0, 0.5f}, {0, 1.5f}, {0, 1.0f}}), 20, "3")
                .find("node 0: more children than k = 2"),
            std::string::npos);
  EXPECT_NE(fileErrorOf(vocabularyBytes(2, 1, {{2, 0.0f}, {0, NAN}, {0, 1.5f}}), 20 + 38 + 2, "nan")
                .find("node 1: weight is not a finite non-negative number"),
            std::string::npos);
  EXPECT_NE(fileErrorOf(vocabularyBytes(2, 1, {{2, 0.0f}, {1, 0.5f}, {0, 1.5f}}), 20 + 38, "1")
                .find("node 1: children beyond the 3 nodes"),
            std::string::npos);
  EXPECT_NE(fileErrorOf(vocabularyBytes(2, 1, {{1, 0.0f}, {1, 0.5f}, {0, 1.5f}}), 20 + 38, "1")
                .find("node 1 at depth 1 has children, but L = 1"),
            std::string::npos);
}

TEST(VocabularyFile, MissingTruncatedAndDirectoryPathsAreFileErrors) {
  const std::string path = ::testing::TempDir() + "bow_truncated.bin";
  {
    std::ofstream out(path, std::ios::binary);
    out << "LTLOBOW1" << std::string(12, '\x01');
  }
  try {
    Vocabulary::load(path);
    FAIL() << "expected an exception";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": byte 8: branching factor"), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
  EXPECT_THROW(Vocabulary::load(path), FileError);
  try {
    Vocabulary::load(::testing::TempDir());
    FAIL() << "expected an exception";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
    EXPECT_EQ(e.offset(), -1);
  }
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
