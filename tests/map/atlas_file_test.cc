// The atlas file (ltlo/map/atlas_file.h): a generated two-map atlas saved and loaded with every
// field compared bit for bit, the rebuilt BoW and keyframe database, and each class of bad file
// refused with its message (file, section, byte offset).
#include "ltlo/map/atlas_file.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <random>
#include <string>

#include "atlas_compare.h"
#include "atlas_file_fixture.h"
#include "bow/vocabulary.h"
#include "ltlo/map/binary_io.h"
#include "map_test_util.h"

namespace ltlo::map {
namespace {

using namespace test;  // the generated atlas and its fixture (atlas_file_fixture.h)

TEST_F(AtlasFileTest, RoundTripKeepsEveryFieldBitForBit) {
  const LoadedAtlas loaded = loadAtlas(path_, *build_, *vocabulary_);
  ASSERT_NE(loaded.atlas, nullptr);
  EXPECT_EQ(loaded.atlas->mapIds(), (std::vector<MapId>{test_.map_a, test_.map_b}));  // the merged map is skipped
  EXPECT_EQ(loaded.atlas->map(test_.map_a)->numKeyFrames(), 6u);
  EXPECT_EQ(loaded.atlas->map(test_.map_a)->originKeyFrames().size(), 2u);
  test::expectSameAtlas(*test_.atlas, *loaded.atlas);

  EXPECT_EQ(loaded.build.vocabulary_checksum, vocabulary_->checksum());
  EXPECT_EQ(loaded.build.settings_summary, build_->settings_summary);
  EXPECT_EQ(loaded.build.built_with, "atlas_file_test");
  const AtlasImuState imu = testImuState();
  EXPECT_EQ(loaded.imu.initialised, true);
  EXPECT_EQ(loaded.imu.bias.b_g, imu.bias.b_g);
  EXPECT_EQ(loaded.imu.bias.b_a, imu.bias.b_a);
  EXPECT_EQ(loaded.imu.g_w, imu.g_w);
  EXPECT_EQ(loaded.imu.acceleration_covariance_w, imu.acceleration_covariance_w);
  EXPECT_EQ(loaded.imu.time_offset_s, imu.time_offset_s);

  // Saving the loaded atlas again writes the same bytes.
  const std::string again = path_ + ".again";
  saveAtlas(*loaded.atlas, loaded.imu, loaded.build, again);
  EXPECT_EQ(readBytes(again), readBytes(path_));
  std::remove(again.c_str());

  const std::uint64_t bytes = std::filesystem::file_size(path_);
  std::printf("test atlas: %llu bytes, 9 keyframes of %d keypoints, %.0f bytes/keyframe\n",
              static_cast<unsigned long long>(bytes), kKeypoints, static_cast<double>(bytes) / 9.0);
}

TEST_F(AtlasFileTest, LoadedBowEqualsAFreshOneAndTheDatabaseAnswersAlike) {
  const LoadedAtlas loaded = loadAtlas(path_, *build_, *vocabulary_);
  for (const MapId id : loaded.atlas->mapIds()) {
    for (const std::shared_ptr<KeyFrame>& kf : loaded.atlas->map(id)->keyFrames()) {
      const auto [bow_vector, feature_vector] = freshBow(*kf, *vocabulary_);
      EXPECT_FALSE(bow_vector.empty());
      EXPECT_EQ(kf->bowVector().entries, bow_vector.entries);
      EXPECT_EQ(kf->featureVector(), feature_vector);
    }
  }
  EXPECT_EQ(loaded.atlas->keyFrameDatabase().size(), 9u);
  // A query: a keyframe's features with a third of them replaced.
  std::mt19937 rng(77);
  const std::shared_ptr<KeyFrame> kf = test_.atlas->map(test_.map_a)->keyFrames()[2];
  features::OrbFeatures features{kf->keypoints(), kf->descriptors()};
  std::uniform_int_distribution<std::uint64_t> bits;
  for (std::size_t i = 0; i < features.descriptors.size(); i += 3)
    features.descriptors[i] = {bits(rng), bits(rng), bits(rng), bits(rng)};
  Frame query(100.0, kf->camera(), kf->T_b_c(), features, std::vector<float>(features.keypoints.size(), 2.0f),
              kf->scaleFactors());
  query.computeBow(*vocabulary_);
  for (const MapId map : {test_.map_a, test_.map_b}) {
    const PlaceQueryOptions options;
    const std::vector<PlaceCandidate> expected =
        test_.atlas->keyFrameDatabase().detectRelocalisationCandidates(query, map, options);
    const std::vector<PlaceCandidate> found =
        loaded.atlas->keyFrameDatabase().detectRelocalisationCandidates(query, map, options);
    ASSERT_EQ(found.size(), expected.size());
    ASSERT_FALSE(found.empty());
    for (std::size_t k = 0; k < found.size(); ++k) {
      EXPECT_EQ(found[k].keyframe->id(), expected[k].keyframe->id());
      EXPECT_EQ(found[k].score, expected[k].score);
      EXPECT_EQ(found[k].group_score, expected[k].group_score);
      EXPECT_EQ(found[k].common_words, expected[k].common_words);
    }
  }
  // The queried keyframe's group wins (its best-scoring member may be a covisible neighbour).
  const std::vector<PlaceCandidate> in_a =
      loaded.atlas->keyFrameDatabase().detectRelocalisationCandidates(query, test_.map_a, PlaceQueryOptions{});
  const std::vector<KeyFrameId> group = kf->bestCovisibles(10);
  EXPECT_TRUE(in_a[0].keyframe->id() == kf->id() ||
              std::find(group.begin(), group.end(), in_a[0].keyframe->id()) != group.end());
}

TEST_F(AtlasFileTest, NewIdsContinueAboveTheFileAndInvariantsHold) {
  const LoadedAtlas loaded = loadAtlas(path_, *build_, *vocabulary_);
  KeyFrameId max_kf;
  MapPointId max_point;
  for (const MapId id : test_.atlas->mapIds()) {
    for (const auto& kf : test_.atlas->map(id)->keyFrames())
      max_kf = max_kf.valid() ? std::max(max_kf, kf->id()) : kf->id();
    for (const auto& p : test_.atlas->map(id)->mapPoints())
      max_point = max_point.valid() ? std::max(max_point, p->id()) : p->id();
  }
  Map& active = loaded.atlas->activeMap();
  EXPECT_EQ(active.id(), test_.map_a);
  std::mt19937 rng(3);
  const std::shared_ptr<KeyFrame> kf = active.createKeyFrame(test::randomFrame(rng, 50.0, SE3(), 20));
  EXPECT_GT(kf->id().value, max_kf.value);
  EXPECT_EQ(active.originKeyFrames().size(), 2u);  // the created-keyframe flag came back: no new origin
  EXPECT_GT(active.createMapPoint(Vec3(0, 0, 1), kf->id())->id().value, max_point.value);
  EXPECT_GT(loaded.atlas->createNewMap().id().value, test_.map_b.value);
  // Both ends of every observation.
  for (const MapId id : {test_.map_a, test_.map_b}) {
    const Map& map = *loaded.atlas->map(id);
    for (const std::shared_ptr<MapPoint>& point : map.mapPoints()) {
      for (const auto& [kf_id, index] : point->observations())
        EXPECT_EQ(map.keyFrame(kf_id)->mapPoint(index), point->id());
    }
  }
}

TEST_F(AtlasFileTest, SummaryCountsMapsSectionsAndExtents) {
  const AtlasFileSummary summary = readAtlasSummary(path_);
  EXPECT_EQ(summary.format_version, 2u);
  EXPECT_FALSE(summary.run.has_value());
  EXPECT_EQ(summary.active_map, test_.map_a);
  EXPECT_EQ(summary.file_bytes, std::filesystem::file_size(path_));
  ASSERT_EQ(summary.maps.size(), 2u);
  const Map& map_a = *test_.atlas->map(test_.map_a);
  EXPECT_EQ(summary.maps[0].keyframes, 6u);
  EXPECT_EQ(summary.maps[0].map_points, map_a.numMapPoints());
  EXPECT_EQ(summary.maps[0].loop_edges, 1u);
  EXPECT_EQ(summary.maps[1].keyframes, 3u);
  EXPECT_EQ(summary.maps[1].map_points, 2u * 20u + 16u);
  EXPECT_EQ(summary.maps[1].loop_edges, 0u);
  EXPECT_EQ(summary.maps[1].t_first_s, 20.0);
  EXPECT_EQ(summary.maps[1].t_last_s, 21.0);
  for (const auto& kf : map_a.keyFrames()) {
    EXPECT_TRUE((kf->cameraCentre_w().array() >= summary.maps[0].extent_min.array()).all());
    EXPECT_TRUE((kf->cameraCentre_w().array() <= summary.maps[0].extent_max.array()).all());
  }
  ASSERT_EQ(summary.sections.size(), 7u);
  std::uint64_t end = 0;
  for (const AtlasFileSummary::Section& section : summary.sections) {
    EXPECT_EQ(section.offset, end) << section.name;
    end = section.offset + section.bytes;
  }
  EXPECT_EQ(end, summary.file_bytes);
  EXPECT_EQ(summary.sections[0].name, "header");
  EXPECT_EQ(summary.sections[0].bytes, 16u + 6u * 36u + 4u);
  EXPECT_EQ(summary.sections[4].name, "keyframes");
}

TEST_F(AtlasFileTest, TruncatedFilesNameTheSectionAndOffset) {
  const std::string bytes = readBytes(path_);
  const std::string bad = path_ + ".bad";
  EXPECT_EQ(loadError(""), bad + ": section header at byte 0: truncated: magic needs 8 bytes (0 left)");
  EXPECT_EQ(loadError(bytes.substr(0, 30)),
            bad + ": section header at byte 16: truncated: section name needs 16 bytes (14 left)");
  const std::uint64_t keyframes = sectionOffset("keyframes"), points = sectionOffset("points");
  const std::string in_keyframes = loadError(bytes.substr(0, keyframes + 1000));
  EXPECT_NE(in_keyframes.find(bad + ": section keyframes at byte " + std::to_string(keyframes) + ": truncated"),
            std::string::npos)
      << in_keyframes;
  const std::string last_byte = loadError(bytes.substr(0, bytes.size() - 1));
  EXPECT_NE(last_byte.find(": section graph at byte " + std::to_string(sectionOffset("graph")) + ": truncated"),
            std::string::npos)
      << last_byte;
  EXPECT_NE(loadError(bytes.substr(0, points)).find("section points at byte " + std::to_string(points) + ": truncated"),
            std::string::npos);
  EXPECT_NE(loadError(bytes + "x")
                .find("section graph at byte " + std::to_string(bytes.size()) + ": bytes after the last section (1)"),
            std::string::npos);
}

TEST_F(AtlasFileTest, WrongMagicAndVersionAreNamed) {
  std::string bytes = readBytes(path_);
  const std::string bad = path_ + ".bad";
  std::string magic = bytes;
  magic[7] = '9';
  EXPECT_EQ(loadError(magic), bad + ": section header at byte 0: not an atlas file (magic is not LTLOATL1) (LTLOATL9)");
  std::string version = bytes;
  version[8] = 3;
  EXPECT_EQ(loadError(version),
            bad + ": section header at byte 8: unsupported format version, this build reads versions 1 to 2 (3)");
}

TEST_F(AtlasFileTest, CrcMismatchNamesTheSection) {
  std::string bytes = readBytes(path_);
  const std::uint64_t points = sectionOffset("points");
  bytes[points + 100] ^= 0x10;
  const std::string message = loadError(bytes);
  EXPECT_NE(
      message.find(path_ + ".bad: section points at byte " + std::to_string(points) + ": CRC mismatch, computed 0x"),
      std::string::npos)
      << message;
  std::string header = readBytes(path_);
  header[16 + 36 + 17] ^= 0x01;  // the imu entry's offset
  EXPECT_NE(loadError(header).find("section header at byte 232: header CRC mismatch"), std::string::npos);
}

TEST_F(AtlasFileTest, AnotherVocabularyIsRefusedByName) {
  const bow::Vocabulary other = trainVocabulary(6);
  ASSERT_NE(other.checksum(), vocabulary_->checksum());
  char expected[256];
  std::snprintf(expected, sizeof(expected),
                ".bad: section build at byte 236: built with vocabulary checksum 0x%016llx (%zu words), this run uses "
                "0x%016llx (%zu words)",
                static_cast<unsigned long long>(vocabulary_->checksum()), vocabulary_->numWords(),
                static_cast<unsigned long long>(other.checksum()), other.numWords());
  EXPECT_EQ(loadError(readBytes(path_), &other), path_ + expected);
}

TEST_F(AtlasFileTest, OtherSettingsAreRefusedShowingBothLines) {
  AtlasBuildInfo expected = makeAtlasBuildInfo(*vocabulary_, mapSettingsSummary(testCalib(520.0), 8, 1.2), "test");
  const std::string message = loadError(readBytes(path_), nullptr, &expected);
  EXPECT_NE(
      message.find("section build at byte 256: built with other map settings: the file has \"camera fx=525 fy=525"),
      std::string::npos)
      << message;
  EXPECT_NE(message.find("this run has \"camera fx=520 fy=525"), std::string::npos) << message;
  EXPECT_EQ(message.find("orb levels"), std::string::npos) << message;  // only the lines that differ
  AtlasBuildInfo any_settings = expected;
  any_settings.settings_summary.clear();
  EXPECT_EQ(loadError(readBytes(path_), nullptr, &any_settings), "");
}

TEST_F(AtlasFileTest, AbsurdCountsAndUnknownIdsAreRefusedBeforeUse) {
  const AtlasFileSummary summary = readAtlasSummary(path_);
  const AtlasFileSummary::Section keyframes = summary.sections[4], graph = summary.sections[6];
  std::string count = readBytes(path_);
  putU64(count, keyframes.offset, 1ULL << 40);
  fixCrcs(count, 3, keyframes.offset, keyframes.bytes);
  EXPECT_EQ(loadError(count), path_ + ".bad: section keyframes at byte " + std::to_string(keyframes.offset) +
                                  ": keyframes count exceeds the bytes left (" + std::to_string(keyframes.bytes - 8) +
                                  ") (1099511627776)");
  std::string unknown = readBytes(path_);
  putU64(unknown, graph.offset + 8, 999999);
  fixCrcs(unknown, 5, graph.offset, graph.bytes);
  EXPECT_EQ(loadError(unknown), path_ + ".bad: section graph at byte " + std::to_string(graph.offset + 8) +
                                    ": graph keyframe is not a keyframe of the file (999999)");
}

TEST_F(AtlasFileTest, SaveIsAtomicAndReplacesAnExistingFileWhole) {
  EXPECT_FALSE(std::filesystem::exists(path_ + ".part"));
  // A smaller atlas over the existing file: the result is exactly that atlas' file.
  Atlas small(vocabulary_->numWords());
  std::mt19937 rng(9);
  buildMap(small.activeMap(), rng, 2, 0.0, *vocabulary_);
  const std::string fresh = path_ + ".fresh";
  saveAtlas(small, AtlasImuState{}, *build_, fresh);
  const std::uint64_t old_size = std::filesystem::file_size(path_);
  saveAtlas(small, AtlasImuState{}, *build_, path_);
  EXPECT_FALSE(std::filesystem::exists(path_ + ".part"));
  EXPECT_LT(std::filesystem::file_size(path_), old_size);
  EXPECT_EQ(readBytes(path_), readBytes(fresh));
  EXPECT_EQ(readAtlasSummary(path_).maps[0].keyframes, 2u);
  std::remove(fresh.c_str());
  const std::string nowhere = ::testing::TempDir() + "/no_such_folder/x.atlas";
  try {
    saveAtlas(small, AtlasImuState{}, *build_, nowhere);
    ADD_FAILURE() << "saved into a missing folder";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find(nowhere + ".part: cannot open the atlas file for writing"),
              std::string::npos);
  }
}

TEST(AtlasSettingsSummary, ShowsEveryMapRelevantSettingExactly) {
  SensorCalib calib = testCalib(525.0);
  calib.camera.lens.model = LensModel::kRadTan;
  calib.camera.lens.k1 = -0.05;
  const std::string summary = mapSettingsSummary(calib, 8, 1.2);
  EXPECT_NE(summary.find("camera fx=525 fy=525 cx=319.5 cy=239.5 width=640 height=480\n"), std::string::npos)
      << summary;
  EXPECT_NE(summary.find("lens radtan k1=-0.050000000000000003 k2=0"), std::string::npos) << summary;
  EXPECT_NE(summary.find("T_b_c q="), std::string::npos);
  EXPECT_NE(summary.find("orb levels=8 scale_factor=1.2\n"), std::string::npos) << summary;
  EXPECT_NE(mapSettingsSummary(calib, 8, 1.2000000000000002), summary);
}

}  // namespace
}  // namespace ltlo::map
