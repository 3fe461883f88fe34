#include "bow/database.h"

#include <gtest/gtest.h>

#include "bow/vocabulary.h"
#include "test_data.h"

namespace bow {
namespace {

class DatabaseTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::mt19937_64 rng(5);
    const std::vector<Descriptor> prototypes = test::makePrototypes(400, rng);
    images_ = test::makeImages(prototypes, 80, 150, 10, rng);
    TrainOptions options;
    options.branching = 8;
    options.depth = 3;
    vocabulary_ = Vocabulary::train(images_, options);
    // Queries: fresh noisy draws of the same images' descriptors.
    for (const auto& image : images_) {
      std::vector<Descriptor> noisy;
      for (const Descriptor& d : image) noisy.push_back(test::flipBits(d, 6, rng));
      BowVector v;
      vocabulary_.transform(noisy, &v);
      queries_.push_back(v);
      vocabulary_.transform(image, &v);
      entries_.push_back(v);
    }
  }
  std::vector<std::vector<Descriptor>> images_;
  Vocabulary vocabulary_;
  std::vector<BowVector> entries_;
  std::vector<BowVector> queries_;
};

TEST_F(DatabaseTest, NoisyQueryFindsItsImageFirstWithTheL1Score) {
  Database db(vocabulary_.numWords());
  for (const BowVector& v : entries_) db.add(v);
  ASSERT_EQ(db.size(), entries_.size());
  int first = 0;
  for (std::size_t i = 0; i < queries_.size(); ++i) {
    const std::vector<QueryResult> results = db.query(queries_[i], 5);
    ASSERT_FALSE(results.empty());
    EXPECT_LE(results.size(), 5u);
    first += results[0].entry == i;
    for (const QueryResult& r : results) EXPECT_NEAR(r.score, l1Score(queries_[i], entries_[r.entry]), 1e-5);
    for (std::size_t j = 1; j < results.size(); ++j) EXPECT_GE(results[j - 1].score, results[j].score);
  }
  EXPECT_GE(first, static_cast<int>(queries_.size()) * 95 / 100);
}

TEST_F(DatabaseTest, FilterAndRemoveExcludeEntries) {
  Database db(vocabulary_.numWords());
  for (const BowVector& v : entries_) db.add(v);
  // Only even entries allowed: the odd query's own image can never come back.
  const std::vector<QueryResult> filtered = db.query(queries_[3], 10, [](EntryId id) { return id % 2 == 0; });
  for (const QueryResult& r : filtered) EXPECT_EQ(r.entry % 2, 0u);
  EXPECT_TRUE(db.remove(3));
  EXPECT_FALSE(db.remove(3));
  EXPECT_EQ(db.entry(3), nullptr);
  for (const QueryResult& r : db.query(queries_[3], 80)) EXPECT_NE(r.entry, 3u);
  const EntryId again = db.add(entries_[3]);
  EXPECT_EQ(again, static_cast<EntryId>(entries_.size()));  // ids are never reused
  EXPECT_EQ(db.query(queries_[3], 1).at(0).entry, again);
}

TEST(Database, RejectsWordOutsideVocabulary) {
  Database db(10);
  BowVector v;
  v.entries = {{3, 0.5f}, {10, 0.5f}};
  EXPECT_THROW(db.add(v), std::invalid_argument);
}

}  // namespace
}  // namespace bow
