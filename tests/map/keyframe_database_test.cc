// KeyFrameDatabase on real photographs (wallpaper packages) with the shipped vocabulary: the right
// keyframe among many for relocalisation, loop (covisible and non-static keyframes excluded,
// covisibility groups collapsed) and merge queries.
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <optional>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "bow/vocabulary.h"
#include "ltlo/map/atlas.h"
#include "map_test_util.h"

#if defined(__SANITIZE_THREAD__)
// cv::imread goes through GDAL, whose uninstrumented global mutexes TSan reports as a lock-order
// inversion inside one thread (the main thread, no other thread involved). Suppressed by name for
// this test binary only; our own locks stay fully checked.
extern "C" const char* __tsan_default_suppressions() {
  return "deadlock:CPLAcquireMutex\ndeadlock:CPLCreateOrAcquireMutexEx\n";
}
#endif

namespace ltlo::map {
namespace {

namespace fs = std::filesystem;

constexpr int kNumPlaces = 12;
constexpr std::size_t kMinKeypoints = 900;  // of the 1000 the extractor aims for

/// Up to kNumPlaces VGA grey crops of the lomiri wallpapers (left and right 4:3 windows of each
/// photograph) that pass `keep`; photographs are decoded only until enough are found.
std::vector<cv::Mat> placeImages(const std::function<bool(const cv::Mat&)>& keep) {
  std::vector<std::string> paths;
  if (fs::is_directory("/usr/share/backgrounds")) {
    for (const fs::directory_entry& e : fs::directory_iterator("/usr/share/backgrounds")) {
      if (e.is_regular_file() && e.path().extension() == ".jpg") paths.push_back(e.path().string());
    }
  }
  std::sort(paths.begin(), paths.end());
  std::vector<cv::Mat> images;
  for (const std::string& path : paths) {
    const cv::Mat photo = cv::imread(path, cv::IMREAD_REDUCED_GRAYSCALE_4);
    if (photo.empty() || photo.rows < 240) continue;
    const int h = photo.rows;
    const int w = std::min(photo.cols / 2, h * 4 / 3);
    for (int side = 0; side < 2; ++side) {
      const int h43 = w * 3 / 4;
      cv::Mat vga;
      cv::resize(photo(cv::Rect(side * (photo.cols - w), (h - h43) / 2, w, h43)), vga, cv::Size(640, 480), 0, 0,
                 cv::INTER_AREA);
      if (keep(vga)) images.push_back(vga);
    }
    if (images.size() >= static_cast<std::size_t>(kNumPlaces)) break;
  }
  images.resize(std::min(images.size(), static_cast<std::size_t>(kNumPlaces)));
  return images;
}

/// Rotation by a few degrees, a shift, a gain and noise: another view of the same place.
cv::Mat perturb(const cv::Mat& image, unsigned seed) {
  cv::RNG rng(seed);
  cv::Mat M = cv::getRotationMatrix2D(cv::Point2f(320.0f, 240.0f), rng.uniform(-4.0, 4.0), rng.uniform(0.95, 1.05));
  M.at<double>(0, 2) += rng.uniform(-15.0, 15.0);
  M.at<double>(1, 2) += rng.uniform(-15.0, 15.0);
  cv::Mat warped;
  cv::warpAffine(image, warped, M, image.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  cv::Mat noise(image.size(), CV_16S);
  rng.fill(noise, cv::RNG::NORMAL, 0, 3);
  cv::Mat out;
  warped.convertTo(out, CV_16S, rng.uniform(0.85, 1.15));
  out += noise;
  out.convertTo(out, CV_8U);
  return out;
}

class KeyFrameDatabaseTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const char* root = std::getenv("LTLO_SOURCE_DIR");
    const std::string path = std::string(root ? root : ".") + "/Vocabulary/ltlo_orb_k10_L5.bin";
    if (!fs::exists(path)) return;
    vocabulary_.emplace(bow::Vocabulary::load(path));
    extractor_.emplace(features::OrbOptions{});
    // Smooth abstract wallpapers are no place to recognise: keep the textured crops.
    images_ =
        placeImages([](const cv::Mat& image) { return extractor_->extract(image).keypoints.size() >= kMinKeypoints; });
  }
  static void TearDownTestSuite() {
    vocabulary_.reset();
    images_.clear();
    extractor_.reset();
  }
  void SetUp() override {
    if (!vocabulary_ || images_.size() < static_cast<std::size_t>(kNumPlaces)) {
      GTEST_SKIP() << "needs Vocabulary/ltlo_orb_k10_L5.bin and " << kNumPlaces << " wallpaper crops";
    }
  }

  /// A frame of `image` with every keypoint at 2 m and its BoW computed.
  static Frame frameOf(const cv::Mat& image, double t_s) {
    features::OrbFeatures f = extractor_->extract(image);
    std::vector<float> depths(f.keypoints.size(), 2.0f);
    Frame frame(t_s, test::vgaCamera(), SE3(), std::move(f), std::move(depths), extractor_->scaleFactors());
    frame.setPose_T_w_b(SE3());
    frame.computeBow(*vocabulary_);
    return frame;
  }
  static std::shared_ptr<KeyFrame> addPlace(Atlas& atlas, const cv::Mat& image, double t_s) {
    std::shared_ptr<KeyFrame> kf = atlas.activeMap().createKeyFrame(frameOf(image, t_s));
    atlas.keyFrameDatabase().add(kf);
    return kf;
  }
  /// Makes a and b covisible through `count` shared points on their first free keypoints.
  static void linkCovisible(Map& map, KeyFrame& a, KeyFrame& b, int first_keypoint, int count) {
    for (int n = 0; n < count; ++n) {
      const std::shared_ptr<MapPoint> p = map.createMapPoint(Vec3(0.0, 0.0, 2.0), a.id());
      map.addObservation(a, first_keypoint + n, *p);
      map.addObservation(b, first_keypoint + n, *p);
    }
    map.updateConnections(a);
    map.updateConnections(b);
  }

  // Loaded once for the suite (vocabulary load and photograph decoding dominate the run time).
  static std::optional<bow::Vocabulary> vocabulary_;
  static std::vector<cv::Mat> images_;
  static std::optional<features::OrbExtractor> extractor_;
};
std::optional<bow::Vocabulary> KeyFrameDatabaseTest::vocabulary_;
std::vector<cv::Mat> KeyFrameDatabaseTest::images_;
std::optional<features::OrbExtractor> KeyFrameDatabaseTest::extractor_;

TEST_F(KeyFrameDatabaseTest, RelocalisationFindsTheRightKeyFrameAmongMany) {
  Atlas atlas(vocabulary_->numWords());
  std::vector<std::shared_ptr<KeyFrame>> places;
  for (int i = 0; i < kNumPlaces; ++i) places.push_back(addPlace(atlas, images_[static_cast<std::size_t>(i)], i));
  EXPECT_EQ(atlas.keyFrameDatabase().size(), static_cast<std::size_t>(kNumPlaces));
  for (int i = 0; i < kNumPlaces; ++i) {
    Frame query = frameOf(perturb(images_[static_cast<std::size_t>(i)], 100 + i), 100.0 + i);
    const std::vector<PlaceCandidate> found =
        atlas.keyFrameDatabase().detectRelocalisationCandidates(query, atlas.activeMapId(), PlaceQueryOptions{});
    ASSERT_FALSE(found.empty()) << "place " << i;
    EXPECT_EQ(found.front().keyframe, places[static_cast<std::size_t>(i)]) << "place " << i;
    EXPECT_GT(found.front().score, 0.05) << "place " << i;
    // Another map is not searched.
    EXPECT_TRUE(atlas.keyFrameDatabase().detectRelocalisationCandidates(query, MapId(99), {}).empty());
  }
  // An erased keyframe is no longer found.
  ASSERT_TRUE(atlas.keyFrameDatabase().erase(places[4]->id()));
  Frame query = frameOf(perturb(images_[4], 200), 200.0);
  for (const PlaceCandidate& c :
       atlas.keyFrameDatabase().detectRelocalisationCandidates(query, atlas.activeMapId(), {})) {
    EXPECT_NE(c.keyframe, places[4]);
  }
}

TEST_F(KeyFrameDatabaseTest, LoopCandidatesSkipCovisibleAndDynamicKeyFramesAndCollapseGroups) {
  Atlas atlas(vocabulary_->numWords());
  Map& map = atlas.activeMap();
  std::vector<std::shared_ptr<KeyFrame>> places;
  for (int i = 0; i < kNumPlaces; ++i) places.push_back(addPlace(atlas, images_[static_cast<std::size_t>(i)], i));
  const std::shared_ptr<KeyFrame> twin = addPlace(atlas, perturb(images_[3], 300), 20.0);  // a second view of place 3
  const std::shared_ptr<KeyFrame> query = addPlace(atlas, perturb(images_[3], 301), 30.0);
  const std::shared_ptr<KeyFrame> place3 = places[3];

  // Place 3 and its twin form one covisibility group: one candidate carries the group's score.
  linkCovisible(map, *place3, *twin, 0, 20);
  std::vector<PlaceCandidate> found = atlas.keyFrameDatabase().detectLoopCandidates(*query, 0.8, {});
  ASSERT_FALSE(found.empty());
  EXPECT_TRUE(found.front().keyframe == place3 || found.front().keyframe == twin);
  const int group_members = static_cast<int>(std::count_if(
      found.begin(), found.end(), [&](const PlaceCandidate& c) { return c.keyframe == place3 || c.keyframe == twin; }));
  EXPECT_EQ(group_members, 1);
  EXPECT_GT(found.front().group_score, found.front().score * 1.5);  // both views contributed

  // Once the query is covisible with the twin (it was tracked against it), only place 3 remains.
  linkCovisible(map, *query, *twin, 100, 20);
  found = atlas.keyFrameDatabase().detectLoopCandidates(*query, 0.8, {});
  ASSERT_FALSE(found.empty());
  EXPECT_EQ(found.front().keyframe, place3);
  const double place3_score = found.front().score;

  // A keyframe whose static area falls below Loop.MinStaticRatio is not a loop candidate.
  place3->setGamma({0.0});
  ASSERT_DOUBLE_EQ(place3->staticAreaRatio(), 0.0);
  found = atlas.keyFrameDatabase().detectLoopCandidates(*query, 0.8, {});
  for (const PlaceCandidate& c : found) {
    EXPECT_NE(c.keyframe, place3);
    EXPECT_NE(c.keyframe, twin);
    EXPECT_LT(c.score, 0.5 * place3_score);  // what is left is a different place
  }
}

TEST_F(KeyFrameDatabaseTest, MergeCandidatesComeFromOtherMaps) {
  Atlas atlas(vocabulary_->numWords());
  std::vector<std::shared_ptr<KeyFrame>> places;
  for (int i = 0; i < kNumPlaces; ++i) places.push_back(addPlace(atlas, images_[static_cast<std::size_t>(i)], i));
  atlas.createNewMap();  // tracking was lost; the robot comes back to place 7
  const std::shared_ptr<KeyFrame> query = addPlace(atlas, perturb(images_[7], 400), 40.0);
  ASSERT_NE(query->mapId(), places[7]->mapId());
  const std::vector<PlaceCandidate> merge = atlas.keyFrameDatabase().detectMergeCandidates(*query, 0.8, {});
  ASSERT_FALSE(merge.empty());
  EXPECT_EQ(merge.front().keyframe, places[7]);
  EXPECT_TRUE(atlas.keyFrameDatabase().detectLoopCandidates(*query, 0.8, {}).empty());
}


TEST_F(KeyFrameDatabaseTest, ReplaceFollowsAChangedBowVector) {
  Atlas atlas(vocabulary_->numWords());
  std::vector<std::shared_ptr<KeyFrame>> places;
  for (int i = 0; i < kNumPlaces; ++i) places.push_back(addPlace(atlas, images_[static_cast<std::size_t>(i)], i));
  // Keyframe 5's static features change (as after a Gamma refinement): here they become place 6's.
  const Frame other = frameOf(images_[6], 50.0);
  places[5]->setBow(other.bowVector(), other.featureVector());
  ASSERT_TRUE(atlas.keyFrameDatabase().replace(places[5]));
  EXPECT_EQ(atlas.keyFrameDatabase().size(), static_cast<std::size_t>(kNumPlaces));
  const Frame query5 = frameOf(perturb(images_[5], 500), 500.0);
  const std::vector<PlaceCandidate> found5 =
      atlas.keyFrameDatabase().detectRelocalisationCandidates(query5, atlas.activeMapId(), {});
  if (!found5.empty()) {
    EXPECT_NE(found5.front().keyframe, places[5]) << "found by its old vector";
  }
  const Frame query6 = frameOf(perturb(images_[6], 501), 501.0);
  const std::vector<PlaceCandidate> found =
      atlas.keyFrameDatabase().detectRelocalisationCandidates(query6, atlas.activeMapId(), {});
  EXPECT_TRUE(std::any_of(found.begin(), found.end(), [&](const PlaceCandidate& c) { return c.keyframe == places[5]; }));
  // A keyframe the database does not hold is left to whoever adds it.
  const std::shared_ptr<KeyFrame> outside = atlas.activeMap().createKeyFrame(frameOf(images_[7], 60.0));
  EXPECT_FALSE(atlas.keyFrameDatabase().replace(outside));
  EXPECT_EQ(atlas.keyFrameDatabase().size(), static_cast<std::size_t>(kNumPlaces));
}

}  // namespace
}  // namespace ltlo::map
