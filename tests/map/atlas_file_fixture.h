#pragma once
// The generated atlas of the atlas file's tests and their fixture (atlas_file_test.cc,
// atlas_run_state_test.cc): two maps, one merged into the first, a map origin, loop edges, refined
// Gamma, saved by SetUp to a file of each test's own; helpers to damage a file and fix its CRCs.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "bow/vocabulary.h"
#include "ltlo/map/atlas_file.h"
#include "ltlo/map/binary_io.h"
#include "map_test_util.h"

namespace ltlo::map::test {

inline constexpr int kKeypoints = 150;

inline std::string tempPath(const std::string& name) { return ::testing::TempDir() + "/atlas_file_test_" + name; }

inline std::string readBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

inline void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// As local mapping computes a keyframe's BoW (src/mapping/local_mapper.cc, staticBow).
inline std::pair<bow::BowVector, bow::FeatureVector> freshBow(const KeyFrame& kf, const bow::Vocabulary& vocabulary) {
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

inline imu::Preintegrated randomPreintegration(std::mt19937& rng, int steps) {
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
inline ClusterSegmentation randomSegmentation(std::mt19937& rng, const std::vector<double>& gamma) {
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
  MapId merged;  ///< merged into map_a
};

inline std::shared_ptr<KeyFrame> addKeyFrame(Map& map, std::mt19937& rng, double t_s, const SE3& T_w_b,
                                             const std::shared_ptr<KeyFrame>& previous,
                                             const bow::Vocabulary& vocabulary) {
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
inline void sharePoints(Map& map, std::mt19937& rng, const std::vector<std::shared_ptr<KeyFrame>>& kfs, int count,
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

inline std::vector<std::shared_ptr<KeyFrame>> buildMap(Map& map, std::mt19937& rng, int num_keyframes, double t0_s,
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

inline TestAtlas makeTestAtlas(const bow::Vocabulary& vocabulary) {
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
  test.merged = merged.id();
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

inline bow::Vocabulary trainVocabulary(unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<std::vector<features::Descriptor>> images;
  for (int k = 0; k < 4; ++k) images.push_back(test::randomFrame(rng, 0.0, SE3(), 300).descriptors());
  return bow::Vocabulary::train(images, bow::TrainOptions{4, 3, 5, 1, 1, 0, {}});
}

inline SensorCalib testCalib(double fx) {
  SensorCalib calib;
  calib.camera.camera = PinholeCamera(fx, 525.0, 319.5, 239.5, 640, 480);
  calib.imu.T_b_c = SE3(so3Exp(Vec3(0.01, -0.02, 0.03)), Vec3(0.05, 0.0, -0.01));
  calib.has_imu = true;
  return calib;
}

inline AtlasImuState testImuState() {
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
                        const AtlasBuildInfo* expected = nullptr, bool restore_run_state = false) {
    const std::string path = path_ + ".bad";
    writeBytes(path, bytes);
    std::string message;
    try {
      loadAtlas(path, expected ? *expected : *build_, vocabulary ? *vocabulary : *vocabulary_, restore_run_state);
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
  static inline bow::Vocabulary* vocabulary_ = nullptr;
  static inline AtlasBuildInfo* build_ = nullptr;
  TestAtlas test_;
  std::string path_;
};

/// Patches the section table entry and header CRC after `bytes` changed inside section `index`
/// (`sections` in the file's table).
inline void fixCrcs(std::string& bytes, int index, std::uint64_t section_offset, std::uint64_t section_bytes,
                    int sections = 6) {
  const std::uint32_t crc = crc32(bytes.data() + section_offset, static_cast<std::size_t>(section_bytes));
  const std::size_t entry = 16 + static_cast<std::size_t>(index) * 36;
  for (int k = 0; k < 4; ++k) bytes[entry + 32 + k] = static_cast<char>((crc >> (8 * k)) & 0xFF);
  const std::size_t header_crc_at = 16 + static_cast<std::size_t>(sections) * 36;
  const std::uint32_t header_crc = crc32(bytes.data(), header_crc_at);
  for (int k = 0; k < 4; ++k) bytes[header_crc_at + k] = static_cast<char>((header_crc >> (8 * k)) & 0xFF);
}

inline std::uint64_t readU64(const std::string& bytes, std::uint64_t at) {
  std::uint64_t value = 0;
  for (int k = 0; k < 8; ++k) value |= static_cast<std::uint64_t>(static_cast<std::uint8_t>(bytes[at + k])) << (8 * k);
  return value;
}

inline void putU64(std::string& bytes, std::uint64_t at, std::uint64_t value) {
  for (int k = 0; k < 8; ++k) bytes[at + k] = static_cast<char>((value >> (8 * k)) & 0xFF);
}

}  // namespace ltlo::map::test
