// The atlas file (ltlo/map/atlas_file.h): a generated two-map atlas saved and loaded with every
// field compared bit for bit, the rebuilt BoW and keyframe database, and each class of bad file
// refused with its message (file, section, byte offset).
#include "ltlo/map/atlas_file.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>

#include "atlas_compare.h"
#include "ltlo/map/binary_io.h"
#include "bow/vocabulary.h"
#include "map_test_util.h"

namespace ltlo::map {
namespace {

constexpr int kKeypoints = 150;

std::string tempPath(const std::string& name) { return ::testing::TempDir() + "/atlas_file_test_" + name; }

std::string readBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// As local mapping computes a keyframe's BoW (src/mapping/local_mapper.cc, staticBow).
std::pair<bow::BowVector, bow::FeatureVector> freshBow(const KeyFrame& kf, const bow::Vocabulary& vocabulary) {
  const std::vector<int> indices = kf.staticKeypoints();
  std::vector<features::Descriptor> descriptors;
  for (const int i : indices) descriptors.push_back(kf.descriptors()[static_cast<std::size_t>(i)]);
  bow::BowVector bow_vector;
  bow::FeatureVector by_position, feature_vector;
  vocabulary.transform(descriptors, &bow_vector, &by_position, 2);
  for (auto& [node, positions] : by_position) {
    for (const std::uint32_t p : positions) feature_vector[node].push_back(static_cast<std::uint32_t>(indices[p]));
  }
  return {bow_vector, feature_vector};
}

imu::Preintegrated randomPreintegration(std::mt19937& rng, int steps) {
  std::normal_distribution<double> noise(0.0, 1.0);
  imu::ImuBias bias;
  bias.b_g = Vec3(0.001, -0.002, 0.003);
  bias.b_a = Vec3(0.02, 0.01, -0.03);
  imu::ImuNoise imu_noise;
  imu_noise.gyro_density = 2e-4;
  imu::Preintegrated pim(bias, imu_noise);
  for (int k = 0; k < steps; ++k) {
    pim.integrateStep(Vec3(0.1 * noise(rng), 0.2 + 0.1 * noise(rng), 0.05 * noise(rng)),
                      Vec3(0.3 * noise(rng), 0.2 * noise(rng), 9.81 + 0.1 * noise(rng)), 0.005 + 1e-4 * k);
  }
  pim.setShifts(0.0012, -0.0007);
  return pim;
}

/// Labels in four vertical bands (clusters 0..2 with depth, 3 = no depth), depth in mm.
ClusterSegmentation randomSegmentation(std::mt19937& rng, const std::vector<double>& gamma) {
  ClusterSegmentation s;
  s.scale = 2;
  s.labels = cv::Mat(240, 320, CV_8U, cv::Scalar(0));
  s.labels.colRange(80, 160).setTo(1);
  s.labels.colRange(160, 280).setTo(2);
  s.labels.colRange(280, 320).setTo(3);
  s.gamma = gamma;
  s.pixel_counts = {80 * 240, 80 * 240, 120 * 240, 40 * 240};
  s.neighbours = {{0, 1}, {1, 2}};
  s.depth_scale = 4;
  s.depth_mm = cv::Mat(120, 160, CV_16U);
  cv::randu(s.depth_mm, cv::Scalar(0), cv::Scalar(5000));
  (void)rng;
  return s;
}

/// The generated atlas: map A (5 keyframes, 2 origins after a merge, a loop edge) and map B (3
/// keyframes, started from A with a MapOrigin), points shared by neighbouring keyframes.
struct TestAtlas {
  std::unique_ptr<Atlas> atlas;
  MapId map_a, map_b;
};

std::shared_ptr<KeyFrame> addKeyFrame(Map& map, std::mt19937& rng, double t_s, const SE3& T_w_b,
                                      const std::shared_ptr<KeyFrame>& previous, const bow::Vocabulary& vocabulary) {
  Frame frame = test::randomFrame(rng, t_s, T_w_b, kKeypoints);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  frame.setSegmentation(randomSegmentation(rng, {1.0, unit(rng), 0.9, 1.0}), 0.5);
  frame.setVelocity(Vec3(0.3 * unit(rng), -0.1, 0.05));
  imu::ImuBias bias;
  bias.b_g = Vec3(1e-3 * unit(rng), 0.0, -2e-4);
  bias.b_a = Vec3(0.0, 0.01 * unit(rng), 0.0);
  frame.setBias(bias);
  if (previous) frame.imu_from_last_keyframe = randomPreintegration(rng, 20);
  frame.computeBow(vocabulary);
  std::shared_ptr<KeyFrame> kf = map.createKeyFrame(frame);
  if (previous) {
    kf->setPreviousKeyFrame(previous->id());
    previous->setNextKeyFrame(kf->id());
  }
  return kf;
}

/// `count` points seen by each of `kfs` at fresh keypoints (next_keypoint counts per keyframe).
void sharePoints(Map& map, std::mt19937& rng, const std::vector<std::shared_ptr<KeyFrame>>& kfs, int count,
                 std::unordered_map<KeyFrameId, int>& next_keypoint) {
  std::uniform_real_distribution<double> coord(-2.0, 2.0), unit(0.0, 1.0);
  for (int n = 0; n < count; ++n) {
    std::shared_ptr<MapPoint> point = map.createMapPoint(Vec3(coord(rng), coord(rng), 3.0 + coord(rng)), KeyFrameId());
    for (const std::shared_ptr<KeyFrame>& kf : kfs) {
      ASSERT_TRUE(map.addObservation(*kf, next_keypoint[kf->id()]++, *point));
    }
    map.updateDescriptor(*point);
    map.updateNormalAndDistances(*point);
    point->setBeta(unit(rng));
    point->increaseVisible(n % 5 + 2);
    point->increaseFound(n % 3);
  }
}

std::vector<std::shared_ptr<KeyFrame>> buildMap(Map& map, std::mt19937& rng, int num_keyframes, double t0_s,
                                                const bow::Vocabulary& vocabulary) {
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  std::unordered_map<KeyFrameId, int> next_keypoint;
  for (int k = 0; k < num_keyframes; ++k) {
    const SE3 T_w_b(so3Exp(Vec3(0.01 * k, 0.2 * k, -0.03)), Vec3(0.3 * k, 0.05 * k, 0.01));
    kfs.push_back(addKeyFrame(map, rng, t0_s + 0.5 * k, T_w_b, kfs.empty() ? nullptr : kfs.back(), vocabulary));
  }
  for (int k = 0; k + 1 < num_keyframes; ++k) sharePoints(map, rng, {kfs[k], kfs[k + 1]}, 20, next_keypoint);
  if (num_keyframes >= 3) sharePoints(map, rng, {kfs[0], kfs[1], kfs[2]}, 16, next_keypoint);
  for (const std::shared_ptr<KeyFrame>& kf : kfs) map.updateConnections(*kf);
  return kfs;
}

TestAtlas makeTestAtlas(const bow::Vocabulary& vocabulary) {
  std::mt19937 rng(31);
  TestAtlas test;
  test.atlas = std::make_unique<Atlas>(vocabulary.numWords());
  Map& map_a = test.atlas->activeMap();
  test.map_a = map_a.id();
  const std::vector<std::shared_ptr<KeyFrame>> a = buildMap(map_a, rng, 5, 0.0, vocabulary);
  a[4]->addLoopEdge(a[0]->id());
  a[0]->addLoopEdge(a[4]->id());
  // Gamma refined after creation (local mapping), with the BoW recomputed as it does.
  a[2]->setGamma({0.2, 0.7, 0.1, 1.0});
  const auto [bow_vector, feature_vector] = freshBow(*a[2], vocabulary);
  a[2]->setBow(bow_vector, feature_vector);
  map_a.setReferenceMapPoints({map_a.mapPoints()[3]->id(), map_a.mapPoints()[7]->id()});

  // A map merged into A: it is skipped, its keyframe and origin move to A.
  Map& merged = test.atlas->createNewMap();
  buildMap(merged, rng, 1, 10.0, vocabulary);
  test.atlas->mergeMaps(merged.id(), map_a.id(), SE3(so3Exp(Vec3(0.0, 0.0, 0.1)), Vec3(1.0, 2.0, 0.0)));

  Map& map_b = test.atlas->createNewMap();
  test.map_b = map_b.id();
  MapOrigin origin;
  origin.parent = map_a.id();
  origin.sigma_position_m = 0.05;
  origin.sigma_rotation_rad = 0.01;
  origin.t_s = 20.0;
  origin.parent_keyframe = a[4]->id();
  origin.imu_across = std::make_shared<imu::Preintegrated>(randomPreintegration(rng, 30));
  origin.T_w_b_parent_keyframe = a[4]->T_w_b();
  const std::vector<std::shared_ptr<KeyFrame>> b = buildMap(map_b, rng, 3, 20.0, vocabulary);
  origin.first_keyframe = b[0]->id();
  map_b.setOrigin(origin);
  test.atlas->setActiveMap(map_a.id());  // not the last one created
  for (const MapId id : test.atlas->mapIds()) {
    for (const std::shared_ptr<KeyFrame>& kf : test.atlas->map(id)->keyFrames()) test.atlas->keyFrameDatabase().add(kf);
  }
  return test;
}

bow::Vocabulary trainVocabulary(unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<std::vector<features::Descriptor>> images;
  for (int k = 0; k < 4; ++k) images.push_back(test::randomFrame(rng, 0.0, SE3(), 300).descriptors());
  return bow::Vocabulary::train(images, bow::TrainOptions{4, 3, 5, 1, 1, 0, {}});
}

SensorCalib testCalib(double fx) {
  SensorCalib calib;
  calib.camera.camera = PinholeCamera(fx, 525.0, 319.5, 239.5, 640, 480);
  calib.imu.T_b_c = SE3(so3Exp(Vec3(0.01, -0.02, 0.03)), Vec3(0.05, 0.0, -0.01));
  calib.has_imu = true;
  return calib;
}

AtlasImuState testImuState() {
  AtlasImuState imu;
  imu.initialised = true;
  imu.bias.b_g = Vec3(1e-3, 2e-3, -3e-3);
  imu.bias.b_a = Vec3(0.1, -0.2, 0.05);
  imu.g_w = Vec3(0.01, -0.02, -9.8);
  imu.acceleration_covariance_w = Mat3::Identity() * 0.3;
  imu.acceleration_covariance_w(0, 2) = imu.acceleration_covariance_w(2, 0) = 0.01;
  imu.time_offset_s = 0.0042;
  return imu;
}

class AtlasFileTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    vocabulary_ = new bow::Vocabulary(trainVocabulary(5));
    build_ = new AtlasBuildInfo(
        makeAtlasBuildInfo(*vocabulary_, mapSettingsSummary(testCalib(525.0), 8, 1.2), "atlas_file_test"));
  }
  static void TearDownTestSuite() {
    delete vocabulary_;
    delete build_;
  }
  void SetUp() override {
    test_ = makeTestAtlas(*vocabulary_);
    path_ = tempPath(::testing::UnitTest::GetInstance()->current_test_info()->name() + std::string(".atlas"));
    saveAtlas(*test_.atlas, testImuState(), *build_, path_);
  }
  void TearDown() override { std::remove(path_.c_str()); }

  /// The message loadAtlas throws for `bytes` (written to a file of its own), "" if it loads.
  std::string loadError(const std::string& bytes, const bow::Vocabulary* vocabulary = nullptr,
                        const AtlasBuildInfo* expected = nullptr) {
    const std::string path = path_ + ".bad";
    writeBytes(path, bytes);
    std::string message;
    try {
      loadAtlas(path, expected ? *expected : *build_, vocabulary ? *vocabulary : *vocabulary_);
    } catch (const AtlasFileError& error) {
      message = error.what();
      EXPECT_EQ(error.file(), path);
    }
    std::remove(path.c_str());
    return message;
  }
  std::uint64_t sectionOffset(const std::string& name) const {
    for (const AtlasFileSummary::Section& section : readAtlasSummary(path_).sections) {
      if (section.name == name) return section.offset;
    }
    ADD_FAILURE() << "no section " << name;
    return 0;
  }
  static bow::Vocabulary* vocabulary_;
  static AtlasBuildInfo* build_;
  TestAtlas test_;
  std::string path_;
};
bow::Vocabulary* AtlasFileTest::vocabulary_ = nullptr;
AtlasBuildInfo* AtlasFileTest::build_ = nullptr;

/// Patches the section table entry and header CRC after `bytes` changed inside section `index`.
void fixCrcs(std::string& bytes, int index, std::uint64_t section_offset, std::uint64_t section_bytes) {
  const std::uint32_t crc = crc32(bytes.data() + section_offset, static_cast<std::size_t>(section_bytes));
  const std::size_t entry = 16 + static_cast<std::size_t>(index) * 36;
  for (int k = 0; k < 4; ++k) bytes[entry + 32 + k] = static_cast<char>((crc >> (8 * k)) & 0xFF);
  const std::size_t header_crc_at = 16 + 6 * 36;
  const std::uint32_t header_crc = crc32(bytes.data(), header_crc_at);
  for (int k = 0; k < 4; ++k) bytes[header_crc_at + k] = static_cast<char>((header_crc >> (8 * k)) & 0xFF);
}

void putU64(std::string& bytes, std::uint64_t at, std::uint64_t value) {
  for (int k = 0; k < 8; ++k) bytes[at + k] = static_cast<char>((value >> (8 * k)) & 0xFF);
}

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
  EXPECT_EQ(summary.format_version, 1u);
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
  version[8] = 2;
  EXPECT_EQ(loadError(version),
            bad + ": section header at byte 8: unsupported format version, this build reads version 1 (2)");
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
