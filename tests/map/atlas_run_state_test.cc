// The atlas file's run state (ltlo/map/run_state_io.h, format version 2): the atlas's part saved
// and restored with every field compared (id counters, map versions, the map merged away, the
// keyframe database's order, anchor and at-rest flags, culled keyframes a stage holds), a frame
// record bit for bit, version-1 files still loading, and a bad run section named in the message.
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "atlas_compare.h"
#include "atlas_file_fixture.h"
#include "ltlo/map/atlas_file.h"
#include "ltlo/map/run_state_io.h"
#include "map_test_util.h"

namespace ltlo::map {
namespace {

using namespace test;  // the generated atlas and its fixture (atlas_file_fixture.h)

constexpr std::uint64_t kStagesTail = 0xfeedfacecafeULL;

/// A run section: the atlas part, then a stages' part holding `held` and a tail value.
std::string runSection(Atlas& atlas, const RunStateHeader& header,
                       const std::vector<std::shared_ptr<const KeyFrame>>& held) {
  KeyFrameRefs refs;
  ByteWriter stages;
  for (const std::shared_ptr<const KeyFrame>& kf : held) refs.write(kf, stages);
  stages.u64(kStagesTail);
  ByteWriter section;
  writeAtlasRunState(atlas, header, refs, section);
  section.raw(stages.bytes().data(), stages.size());
  return section.bytes();
}

class AtlasRunStateTest : public AtlasFileTest {
 protected:
  /// The test atlas as a run leaves it: a[3] culled, then a[2] (a[3]'s parent, so a culled chain
  /// a[3] -> a[2] -> a[1]), a[1] an anchor, a keyframe made at rest in map B, the database
  /// re-ordered (a[0] added last), versions bumped; saved with a run state whose stages hold a[3]
  /// and a[4].
  void SetUp() override {
    AtlasFileTest::SetUp();
    Atlas& atlas = *test_.atlas;
    Map& map_a = *atlas.map(test_.map_a);
    a_ = map_a.keyFrames();
    ASSERT_EQ(a_.size(), 6u);
    for (const int k : {3, 2}) {
      ASSERT_TRUE(map_a.eraseKeyFrame(a_[k]->id()));
      atlas.keyFrameDatabase().erase(a_[k]->id());
    }
    atlas.keyFrameDatabase().erase(a_[0]->id());
    atlas.keyFrameDatabase().add(a_[0]);
    a_[1]->markAnchor();
    std::mt19937 rng(41);
    Frame still = randomFrame(rng, 30.0, SE3(), 50);
    still.at_rest = true;
    still.computeBow(*vocabulary_);
    at_rest_ = atlas.map(test_.map_b)->createKeyFrame(still);
    atlas.keyFrameDatabase().add(at_rest_);
    atlas.map(test_.map_b)->bumpVersion();
    run_state_ = runSection(atlas, header_, {a_[3], a_[4]});
    saveAtlas(atlas, testImuState(), *build_, path_, &run_state_);
  }

  const RunStateHeader header_{675, 22.466667};
  std::vector<std::shared_ptr<KeyFrame>> a_;
  std::shared_ptr<KeyFrame> at_rest_;
  std::string run_state_;
};

TEST_F(AtlasRunStateTest, RestoresTheAtlasAsTheRunLeftIt) {
  Atlas& atlas = *test_.atlas;
  const LoadedAtlas loaded = loadAtlas(path_, *build_, *vocabulary_, true);
  ASSERT_TRUE(loaded.run.has_value());
  Atlas& restored = *loaded.atlas;
  expectSameAtlas(atlas, restored);
  EXPECT_EQ(loaded.run->header.next_frame_index, 675u);
  EXPECT_EQ(loaded.run->header.last_frame_t_s, 22.466667);
  for (const MapId id : atlas.mapIds()) EXPECT_EQ(restored.map(id)->version(), atlas.map(id)->version()) << id;
  // The map merged away: empty, left out of mapIds(), followed by resolve(), version kept.
  ASSERT_NE(restored.map(test_.merged), nullptr);
  EXPECT_EQ(restored.resolve(test_.merged), test_.map_a);
  EXPECT_EQ(restored.map(test_.merged)->numKeyFrames(), 0u);
  EXPECT_EQ(restored.map(test_.merged)->version(), atlas.map(test_.merged)->version());
  EXPECT_EQ(restored.mapIds(), atlas.mapIds());
  EXPECT_EQ(restored.keyFrameDatabase().keyFrameIdsInOrder(), atlas.keyFrameDatabase().keyFrameIdsInOrder());
  const std::vector<KeyFrameId> order = restored.keyFrameDatabase().keyFrameIdsInOrder();
  ASSERT_GE(order.size(), 2u);
  EXPECT_EQ(order[order.size() - 2], a_[0]->id());  // re-added, then the keyframe at rest
  EXPECT_EQ(order.back(), at_rest_->id());
  for (const MapId id : atlas.mapIds()) {
    for (const std::shared_ptr<KeyFrame>& kf : atlas.map(id)->keyFrames()) {
      const std::shared_ptr<KeyFrame> other = restored.map(id)->keyFrame(kf->id());
      EXPECT_EQ(other->isAnchor(), kf->isAnchor()) << kf->id();
      EXPECT_EQ(other->atRest(), kf->atRest()) << kf->id();
    }
  }
  EXPECT_TRUE(restored.map(test_.map_a)->keyFrame(a_[1]->id())->isAnchor());
  EXPECT_TRUE(restored.map(test_.map_b)->keyFrame(at_rest_->id())->atRest());

  // The stages' part names the culled a[3], whose chain runs through a[2] to the live a[1].
  ByteReader stages = loaded.run->stages();
  const std::shared_ptr<KeyFrame> culled = loaded.run->keyframes.read(stages, "held keyframe");
  const std::shared_ptr<KeyFrame> live = loaded.run->keyframes.read(stages, "held keyframe");
  EXPECT_EQ(stages.u64("tail"), kStagesTail);
  stages.expectEnd();
  ASSERT_NE(culled, nullptr);
  EXPECT_EQ(culled->id(), a_[3]->id());
  EXPECT_TRUE(culled->isBad());
  EXPECT_EQ(culled->mapId(), a_[3]->mapId());
  EXPECT_EQ(culled->t_s(), a_[3]->t_s());
  expectSameSe3(culled->T_w_b(), a_[3]->T_w_b(), "culled T_w_b");
  expectSameSe3(culled->T_b_c(), a_[3]->T_b_c(), "culled T_b_c");
  EXPECT_EQ(culled->v_w_b(), a_[3]->v_w_b());
  EXPECT_EQ(culled->bias().b_a, a_[3]->bias().b_a);
  EXPECT_EQ(culled->culledParent()->id(), a_[2]->id());
  EXPECT_TRUE(culled->culledParent()->isBad());
  EXPECT_EQ(culled->culledParent()->culledParent()->id(), a_[1]->id());
  expectSameSe3(culled->T_parent_this(), a_[3]->T_parent_this(), "culled T_parent_this");
  // A correction of the live end moves the culled ones alike in both atlases.
  const SE3 move(so3Exp(Vec3(0.0, 0.0, 0.2)), Vec3(0.5, -0.1, 0.0));
  a_[1]->setPose_T_w_b(move * a_[1]->T_w_b());
  restored.map(test_.map_a)
      ->keyFrame(a_[1]->id())
      ->setPose_T_w_b(move * culled->culledParent()->culledParent()->T_w_b());
  expectSameSe3(latestPose_T_w_b(*culled), latestPose_T_w_b(*a_[3]), "culled latest pose");
  EXPECT_EQ(live, restored.map(test_.map_a)->keyFrame(a_[4]->id()));
  EXPECT_EQ(loaded.summary.run->culled_keyframes, 2u);
  EXPECT_EQ(loaded.summary.run->merged_maps, 1u);
  EXPECT_EQ(loaded.summary.run->stage_bytes, 8u * 3u);

  // New objects get the ids the saved run would have given next.
  std::mt19937 rng(5);
  EXPECT_EQ(restored.map(test_.map_b)->createKeyFrame(randomFrame(rng, 40.0, SE3(), 10))->id(),
            atlas.map(test_.map_b)->createKeyFrame(randomFrame(rng, 40.0, SE3(), 10))->id());
  EXPECT_EQ(restored.map(test_.map_b)->createMapPoint(Vec3(0, 0, 1), KeyFrameId())->id(),
            atlas.map(test_.map_b)->createMapPoint(Vec3(0, 0, 1), KeyFrameId())->id());
  EXPECT_EQ(restored.createNewMap().id(), atlas.createNewMap().id());
}

TEST_F(AtlasRunStateTest, SavingTheRestoredAtlasAgainWritesTheSameBytes) {
  const LoadedAtlas loaded = loadAtlas(path_, *build_, *vocabulary_, true);
  ByteReader stages = loaded.run->stages();
  const std::shared_ptr<KeyFrame> culled = loaded.run->keyframes.read(stages, "held keyframe");
  const std::shared_ptr<KeyFrame> live = loaded.run->keyframes.read(stages, "held keyframe");
  const std::string again = runSection(*loaded.atlas, loaded.run->header, {culled, live});
  EXPECT_EQ(again, run_state_);
  const std::string path = path_ + ".again";
  saveAtlas(*loaded.atlas, loaded.imu, loaded.build, path, &again);
  EXPECT_EQ(readBytes(path), readBytes(path_));
  std::remove(path.c_str());
}

TEST_F(AtlasRunStateTest, WithoutResumingTheFileLoadsAsBefore) {
  const LoadedAtlas loaded = loadAtlas(path_, *build_, *vocabulary_);
  EXPECT_FALSE(loaded.run.has_value());
  expectSameAtlas(*test_.atlas, *loaded.atlas);
  // No run state applied: no anchor, no merged map kept, the database in the loader's order.
  EXPECT_FALSE(loaded.atlas->map(test_.map_a)->keyFrame(a_[1]->id())->isAnchor());
  EXPECT_EQ(loaded.atlas->map(test_.merged), nullptr);
  const AtlasFileSummary summary = readAtlasSummary(path_);
  EXPECT_EQ(summary.format_version, 2u);
  ASSERT_TRUE(summary.run.has_value());
  EXPECT_EQ(summary.run->next_frame_index, 675u);
  ASSERT_EQ(summary.sections.size(), 8u);
  EXPECT_EQ(summary.sections.back().name, "run");
  EXPECT_EQ(summary.sections.back().bytes, run_state_.size());
}

TEST_F(AtlasRunStateTest, VersionOneFilesStillLoadAndHaveNothingToResume) {
  // The fixture's plain file (version 2, six sections) made a version-1 file.
  const std::string plain_path = path_ + ".plain";
  saveAtlas(*test_.atlas, testImuState(), *build_, plain_path);
  std::string bytes = readBytes(plain_path);
  std::remove(plain_path.c_str());
  bytes[8] = 1;
  const std::size_t header_crc_at = 16 + 6 * 36;
  const std::uint32_t header_crc = crc32(bytes.data(), header_crc_at);
  for (int k = 0; k < 4; ++k) bytes[header_crc_at + k] = static_cast<char>((header_crc >> (8 * k)) & 0xFF);
  EXPECT_EQ(loadError(bytes), "");
  EXPECT_EQ(readAtlasSummaryFromBytes(bytes, "v1").format_version, 1u);
  EXPECT_EQ(loadError(bytes, nullptr, nullptr, true),
            path_ + ".bad: section run at byte " + std::to_string(bytes.size()) +
                ": no run state to resume from (the file was saved without one, or by a build before format "
                "version 2)");
  // A version-1 header cannot announce the run section.
  std::string seven = readBytes(path_);
  seven[8] = 1;
  EXPECT_EQ(loadError(seven), path_ + ".bad: section header at byte 12: version 1 has 6 sections (7)");
}

TEST_F(AtlasRunStateTest, ABadRunSectionIsNamedWithItsByte) {
  const std::string bytes = readBytes(path_);
  const AtlasFileSummary summary = readAtlasSummary(path_);
  const AtlasFileSummary::Section run = summary.sections.back();
  const std::string bad = path_ + ".bad";

  std::string flipped = bytes;
  flipped[run.offset + 20] ^= 0x04;
  const std::string crc = loadError(flipped);
  EXPECT_NE(crc.find(bad + ": section run at byte " + std::to_string(run.offset) + ": CRC mismatch, computed 0x"),
            std::string::npos)
      << crc;

  // Cut short inside the culled keyframes, its length and CRCs made right: the header reads, the
  // count of culled keyframes no longer fits in the bytes left (refused before anything is made).
  std::string cut = bytes.substr(0, bytes.size() - 8 * 3 - 40);
  putU64(cut, 16 + 6 * 36 + 24, run.bytes - 8 * 3 - 40);
  fixCrcs(cut, 6, run.offset, run.bytes - 8 * 3 - 40, 7);
  EXPECT_EQ(loadError(cut), "");  // not resuming: the run section is not read
  const std::string truncated = loadError(cut, nullptr, nullptr, true);
  EXPECT_NE(truncated.find(bad + ": section run at byte "), std::string::npos) << truncated;
  EXPECT_NE(truncated.find(": culled keyframes count exceeds the bytes left"), std::string::npos) << truncated;

  // Id counters below the file's ids: new objects would collide with loaded ones.
  std::string counters = bytes;
  const std::uint64_t counters_at = run.offset + 16;
  putU64(counters, counters_at, 1);
  fixCrcs(counters, 6, run.offset, run.bytes, 7);
  EXPECT_EQ(loadError(counters, nullptr, nullptr, true),
            bad + ": section run at byte " + std::to_string(counters_at) +
                ": id counters not above the file's ids (keyframe, point, map) (1, " +
                std::to_string(readU64(bytes, counters_at + 8)) + ", " +
                std::to_string(readU64(bytes, counters_at + 16)) + ")");
}

TEST(AtlasRunStateRecords, AFrameRecordKeepsEveryField) {
  const bow::Vocabulary vocabulary = trainVocabulary(5);
  std::mt19937 rng(12);
  Frame frame = randomFrame(rng, 3.25, SE3(so3Exp(Vec3(0.1, -0.2, 0.3)), Vec3(1.0, 2.0, 0.5)), 120);
  frame.setSegmentation(randomSegmentation(rng, {1.0, 0.3, 0.8, 1.0}), 0.6);
  frame.setVelocity(Vec3(0.2, -0.1, 0.05));
  imu::ImuBias bias;
  bias.b_g = Vec3(1e-3, -2e-3, 5e-4);
  bias.b_a = Vec3(0.02, 0.0, -0.01);
  frame.setBias(bias);
  frame.imu_from_last_keyframe = randomPreintegration(rng, 15);
  frame.imu_from_last_frame = randomPreintegration(rng, 6);
  for (int k = 0; k < 4; ++k) {
    ImuSample sample;
    sample.t_s = 3.2 + 0.005 * k;
    sample.gyro_rad_s = Vec3(0.01 * k, 0.1, -0.02);
    sample.acc_m_s2 = Vec3(0.1, -0.2 * k, 9.81);
    frame.imu_samples.push_back(sample);
  }
  frame.at_rest = true;
  frame.reference_keyframe = KeyFrameId(7);
  frame.map_points[3] = MapPointId(11);
  frame.map_points[50] = MapPointId(12);
  frame.outliers[50] = true;
  frame.computeBow(vocabulary);

  ByteWriter out;
  writeFrame(frame, out);
  ByteReader in(out.bytes().data(), out.size(), "test.atlas", "run", 100);
  const Frame back = readFrame(in, &vocabulary);
  in.expectEnd();
  EXPECT_EQ(back.t_s(), frame.t_s());
  EXPECT_EQ(back.camera().K(), frame.camera().K());
  expectSameSe3(back.T_b_c(), frame.T_b_c(), "T_b_c");
  ASSERT_EQ(back.numKeypoints(), frame.numKeypoints());
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    const features::Keypoint& a = frame.keypoints()[static_cast<std::size_t>(i)];
    const features::Keypoint& b = back.keypoints()[static_cast<std::size_t>(i)];
    EXPECT_TRUE(a.x_px == b.x_px && a.y_px == b.y_px && a.angle_deg == b.angle_deg && a.response == b.response &&
                a.octave == b.octave)
        << i;
    EXPECT_EQ(back.descriptors()[static_cast<std::size_t>(i)], frame.descriptors()[static_cast<std::size_t>(i)]);
    EXPECT_EQ(back.p_c(i), frame.p_c(i));
  }
  EXPECT_EQ(back.depths_m(), frame.depths_m());
  EXPECT_EQ(back.scaleFactors(), frame.scaleFactors());
  expectSameSegmentation(back.segmentation(), frame.segmentation(), "segmentation");
  EXPECT_EQ(back.staticThreshold(), frame.staticThreshold());
  EXPECT_EQ(back.keypointClusters(), frame.keypointClusters());
  EXPECT_EQ(back.featuresInArea(320.0f, 240.0f, 200.0f), frame.featuresInArea(320.0f, 240.0f, 200.0f));
  ASSERT_TRUE(back.hasBow());
  EXPECT_EQ(back.bowVector().entries, frame.bowVector().entries);
  EXPECT_EQ(back.featureVector(), frame.featureVector());
  expectSameSe3(back.T_w_b(), frame.T_w_b(), "T_w_b");
  EXPECT_EQ(back.v_w_b(), frame.v_w_b());
  EXPECT_EQ(back.bias().b_g, frame.bias().b_g);
  EXPECT_EQ(back.bias().b_a, frame.bias().b_a);
  expectSamePreintegration(*back.imu_from_last_keyframe, *frame.imu_from_last_keyframe, "imu_from_last_keyframe");
  expectSamePreintegration(*back.imu_from_last_frame, *frame.imu_from_last_frame, "imu_from_last_frame");
  ASSERT_EQ(back.imu_samples.size(), frame.imu_samples.size());
  for (std::size_t k = 0; k < frame.imu_samples.size(); ++k) {
    EXPECT_EQ(back.imu_samples[k].t_s, frame.imu_samples[k].t_s);
    EXPECT_EQ(back.imu_samples[k].gyro_rad_s, frame.imu_samples[k].gyro_rad_s);
    EXPECT_EQ(back.imu_samples[k].acc_m_s2, frame.imu_samples[k].acc_m_s2);
  }
  EXPECT_TRUE(back.at_rest);
  EXPECT_EQ(back.reference_keyframe, frame.reference_keyframe);
  EXPECT_EQ(back.map_points, frame.map_points);
  EXPECT_EQ(back.outliers, frame.outliers);

  // A record cut short names the file, the section and the byte of the field.
  ByteReader cut(out.bytes().data(), out.size() - 5, "test.atlas", "run", 100);
  try {
    (void)readFrame(cut, nullptr);
    ADD_FAILURE() << "a cut frame record was read";
  } catch (const AtlasFileError& error) {
    EXPECT_EQ(error.section(), "run");
    EXPECT_NE(std::string(error.what()).find("test.atlas: section run at byte "), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("truncated: frame outlier flag"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace ltlo::map
