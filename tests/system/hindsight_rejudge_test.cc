// Hindsight re-judging (hindsight_rejudge.h, Seg.HindsightRejudge) on generated RGB-D frames: the room
// of segmentation/dense_scene.h, the camera moving, a textured box over most of the view moving through
// the world at its own pace. The Gamma step judged at the true poses finds the room static and the box
// dynamic; at a reference pose 3 cm off (a dead-reckoned stretch) it calls part of the room dynamic.
#include "ltlo/system/hindsight_rejudge.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "segmentation/dense_scene.h"

namespace ltlo::system {
namespace {

using segmentation::test::kDt;
using segmentation::test::Scene;

constexpr double kBaselineS = 0.3;

Scene movingBoxScene() {
  Scene scene;
  scene.v_w_b = Vec3(0.05, 0.0, 0.3);
  scene.omega_b = Vec3(0.01, 0.1, 0.0);
  scene.depth_noise = true;
  scene.box_in_world = true;
  scene.box_velocity_w = Vec3(0.0, 0.0, -0.2);  // pushed towards the camera
  return scene;
}

RejudgeOptions rejudgeOptions() {
  RejudgeOptions options;
  const SegmentationOptions segmentation = segmentation::test::segmentationOptions();
  const DenseOptions dense = segmentation::test::denseOptions();
  options.frame = segmentation::DenseFrameOptions::from(segmentation, dense);
  options.solver = segmentation::DenseSolverOptions::from(segmentation, dense, LocalMappingOptions());
  options.clusters = segmentation::DepthKMeansOptions::from(segmentation);
  options.reference_baseline_s = kBaselineS;
  return options;
}

io::RgbdImuFrame frameAt(const Scene& scene, double t_s, cv::Mat* truth = nullptr) {
  const segmentation::test::RgbdFrame rendered = scene.render(t_s);
  io::RgbdImuFrame frame;
  frame.t_s = t_s;
  frame.color_bgr = rendered.color_bgr;
  frame.depth_m = rendered.depth_m;
  frame.mask = rendered.dynamic.clone();  // the online mask: the truth
  if (truth != nullptr) *truth = rendered.dynamic;
  return frame;
}

SE3 cameraPose(const Scene& scene, double t_s) { return scene.T_w_b(t_s) * scene.T_b_c; }

/// IoU of the static pixels of `mask` against `truth` (both 255 = dynamic).
double staticIou(const cv::Mat& mask, const cv::Mat& truth) {
  int intersection = 0, union_count = 0;
  for (int r = 0; r < truth.rows; ++r) {
    for (int c = 0; c < truth.cols; ++c) {
      const bool est_static = mask.at<std::uint8_t>(r, c) < 128, true_static = truth.at<std::uint8_t>(r, c) < 128;
      intersection += est_static && true_static;
      union_count += est_static || true_static;
    }
  }
  return static_cast<double>(intersection) / union_count;
}

/// The current frame's mask judged at the true poses, the earlier frames' positions off as a velocity
/// error `velocity_error_w` makes them (dead reckoning: the error grows with the time back), from an
/// online mask `online` (255: all dynamic, so every static pixel is the solve's).
double rejudgedIou(const Vec3& velocity_error_w, int online = 255, bool* judged = nullptr) {
  const Scene scene = movingBoxScene();
  const CameraModel camera(scene.camera, LensDistortion());
  HindsightRejudger rejudger(camera, std::make_shared<const Undistorter>(), rejudgeOptions());
  cv::Mat truth;
  const io::RgbdImuFrame reference = frameAt(scene, -kBaselineS);
  const io::RgbdImuFrame previous = frameAt(scene, 0.0);
  const io::RgbdImuFrame current = frameAt(scene, kDt, &truth);
  const auto shifted = [&](double t_s) {
    return SE3(Quat::Identity(), velocity_error_w * (t_s - kDt)) * cameraPose(scene, t_s);
  };
  const io::RgbdImuFrame* frames[] = {&reference, &previous, &current};
  int loads = 0;
  const auto load = [&](int index) {
    ++loads;
    return *frames[index];
  };
  cv::Mat mask(truth.size(), CV_8U, cv::Scalar(online));
  const bool ok = rejudger.rejudge(2, cameraPose(scene, kDt), 1, shifted(0.0), 0, shifted(-kBaselineS), load, &mask);
  EXPECT_EQ(loads, 3);
  // Judged again, the three frames come from the cache.
  cv::Mat again(truth.size(), CV_8U, cv::Scalar(online));
  EXPECT_TRUE(rejudger.rejudge(2, cameraPose(scene, kDt), 1, shifted(0.0), 0, shifted(-kBaselineS), load, &again));
  EXPECT_EQ(loads, 3);
  EXPECT_EQ(cv::countNonZero(again != mask), 0);
  if (judged != nullptr) *judged = ok;
  EXPECT_EQ(mask.size(), truth.size());
  return staticIou(mask, truth);
}

// An online mask that called the whole view dynamic (the room misaligned by a wrong motion), judged at
// the true poses: the room is static and the box coming towards the camera dynamic (measured 0.995).
// The same frames with the earlier frames placed by a velocity 0.2 m/s off along the optical axis (6.7
// cm over the reference baseline) call most of the room dynamic (0.33): the poses decide.
TEST(HindsightRejudge, AtTheFinalPosesTheRoomIsStaticWhereTheOnlineMaskCalledItDynamic) {
  bool judged = false;
  const double at_truth = rejudgedIou(Vec3::Zero(), 255, &judged);
  ASSERT_TRUE(judged);
  EXPECT_GT(at_truth, 0.98);
  EXPECT_LT(rejudgedIou(Vec3(0.0, 0.0, 0.2)), 0.5);
}

// Re-judging only turns the online mask's dynamic pixels static: where the online mask called the box
// static, it stays static (the static IoU is the box-and-room share of an all-static mask).
TEST(HindsightRejudge, APixelTheOnlineMaskCalledStaticStaysStatic) {
  const Scene scene = movingBoxScene();
  cv::Mat truth;
  frameAt(scene, kDt, &truth);
  const double all_static = static_cast<double>(cv::countNonZero(truth < 128)) / truth.total();
  EXPECT_NEAR(rejudgedIou(Vec3::Zero(), 0), all_static, 1e-12);
}

// The gate: the mean shift of the frame's surface in the reference camera between the online and the
// final relative pose. No shift where they agree; a 3 cm error at 1-2 m is several label pixels; poses
// in two maps cannot be compared.
TEST(HindsightRejudge, TheGateMeasuresHowFarTheOnlineMotionMovedTheSurface) {
  const Scene scene = movingBoxScene();
  const CameraModel camera(scene.camera, LensDistortion());
  const HindsightRejudger rejudger(camera, std::make_shared<const Undistorter>(), rejudgeOptions());
  const io::RgbdImuFrame current = frameAt(scene, kDt);
  const SE3 cur = cameraPose(scene, kDt), ref = cameraPose(scene, -kBaselineS);
  const SE3 ref_off = ref * SE3(Quat::Identity(), Vec3(0.03, 0.0, 0.0));
  RejudgePoses current_poses{&cur, &cur, 1};
  RejudgePoses reference_poses{&ref, &ref, 1};
  EXPECT_NEAR(rejudger.onlineShiftPx(current.depth_m, current_poses, reference_poses), 0.0, 1e-9);
  RejudgePoses reference_off{&ref, &ref_off, 1};
  const double shift_px = rejudger.onlineShiftPx(current.depth_m, current_poses, reference_off);
  // 3 cm at 1.1-3 m depth and fx 262.5 at the label resolution: 2.6-7.2 px.
  EXPECT_GT(shift_px, 2.5);
  EXPECT_LT(shift_px, 7.5);
  reference_off.online_map = 2;
  EXPECT_EQ(rejudger.onlineShiftPx(current.depth_m, current_poses, reference_off),
            std::numeric_limits<double>::infinity());
  const RejudgePoses no_final{nullptr, &ref, 1};
  EXPECT_EQ(rejudger.onlineShiftPx(current.depth_m, current_poses, no_final), -1.0);
}

}  // namespace
}  // namespace ltlo::system
