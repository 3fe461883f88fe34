// The robust VIBA (thesis Eq. 50-58) on a generated visual-inertial window: a box appears in front
// of the camera and moves along with it (the worst case: its features say the camera stands still)
// while the IMU and the static background say it moves. Every keyframe starts from a pose dragged
// towards the box, with depth clusters all static (gamma = 1, as Seg.DenseInit = 0 gives). The
// robust VIBA recovers the static poses, deletes the box's points and marks the box's clusters
// dynamic; the plain VIBA on the same window stays dragged.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "../../src/mapping/local_window_ba.h"
#include "common/analytic_trajectory.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/map.h"

namespace ltlo::mapping {
namespace {

constexpr int kNumKeyFrames = 7;       // kf0 (fixed border) .. kf6
constexpr int kFirstBoxKeyFrame = 2;   // the box is in view from kf2 on
constexpr double kSpacing_s = 0.25;
constexpr double kSphereRadius_m = 5.0;
constexpr double kBoxDepth_m = 1.2;
constexpr int kLabelScale = 2;
constexpr int kDepthScale = 4;
const Vec3 kSphereCentre_w(0.0, 0.3, 0.0);

PinholeCamera camera() { return PinholeCamera(262.5, 262.5, 159.5, 119.5, 320, 240); }
std::vector<float> scaleFactors() { return {1.0f, 1.2f, 1.44f, 1.728f}; }
std::vector<float> levelSigma2() { return {1.0f, 1.44f, 2.0736f, 2.985984f}; }

/// Camera looking along the body x axis (z_c = x_b), slightly offset.
SE3 bodyToCamera() {
  Mat3 R_b_c;
  R_b_c << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return SE3(R_b_c, Vec3(0.05, -0.02, 0.01));
}

/// The box: a 0.8 x 0.7 m rectangle 1.2 m ahead of the camera (a third of the image), sliding
/// 4 cm per keyframe.
struct Box {
  double x_min, x_max, y_min, y_max;  // camera frame at depth kBoxDepth_m
  bool contains(const Vec3& p_c) const {  // the ray through p_c hits the box in front of p_c
    const double s = kBoxDepth_m / p_c.z();
    const double x = p_c.x() * s, y = p_c.y() * s;
    return p_c.z() > kBoxDepth_m && x >= x_min && x <= x_max && y >= y_min && y <= y_max;
  }
};
Box boxAt(int k) {
  const double shift = 0.04 * (k - kFirstBoxKeyFrame);
  return {-0.5 + shift, 0.3 + shift, -0.35, 0.35};
}

/// Depth of the background sphere along the camera ray through pixel (u, v) of pose T_w_c.
double sphereDepth(const SE3& T_w_c, double u, double v) {
  const Vec3 ray_c = camera().backProject(Vec2(u, v), 1.0);  // z = 1
  const Vec3 d_w = T_w_c.rotationMatrix() * ray_c;
  const Vec3 o = T_w_c.translation() - kSphereCentre_w;
  const double a = d_w.squaredNorm(), b = 2.0 * o.dot(d_w), c = o.squaredNorm() - kSphereRadius_m * kSphereRadius_m;
  return (-b + std::sqrt(b * b - 4.0 * a * c)) / (2.0 * a);  // ray parameter = depth (ray_c.z = 1)
}

struct Scene {
  std::vector<SE3> T_w_b_true;
  std::vector<Vec3> v_w_b_true;
  std::vector<Vec3> static_w;
  std::vector<Vec2> box_local;  // (x, y) on the box face
};

Scene makeScene(std::mt19937& rng) {
  Scene scene;
  const imu::test::AnalyticTrajectory trajectory;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    const imu::NavState s = trajectory.state(1.0 + kSpacing_s * k);
    scene.T_w_b_true.emplace_back(s.R_w_b, s.p_w_b);
    scene.v_w_b_true.push_back(s.v_w_b);
  }
  // Static points on the sphere, on the side the camera looks at.
  std::normal_distribution<double> normal(0.0, 1.0);
  const Vec3 forward_w = (scene.T_w_b_true[3] * bodyToCamera()).rotationMatrix().col(2);
  while (scene.static_w.size() < 600) {
    const Vec3 d = Vec3(normal(rng), normal(rng), normal(rng)).normalized();
    if (d.dot(forward_w) > 0.3) scene.static_w.push_back(kSphereCentre_w + kSphereRadius_m * d);
  }
  // A textured box: a third of the features in view.
  std::uniform_real_distribution<double> bx(-0.45, 0.25), by(-0.3, 0.3);
  for (int n = 0; n < 150; ++n) scene.box_local.emplace_back(bx(rng), by(rng));
  return scene;
}

/// Cluster of label pixel (col, row): box left/right halves 0, 1; background quadrants 2..5.
int clusterOfPixel(const SE3& T_w_c, int k, double u, double v) {
  if (k >= kFirstBoxKeyFrame) {
    const Vec3 far_c = camera().backProject(Vec2(u, v), 10.0);
    const Box box = boxAt(k);
    if (box.contains(far_c)) return far_c.x() * kBoxDepth_m / 10.0 < 0.5 * (box.x_min + box.x_max) ? 0 : 1;
  }
  (void)T_w_c;
  return 2 + (v >= 120.0 ? 2 : 0) + (u >= 160.0 ? 1 : 0);
}

map::ClusterSegmentation segmentationOf(const SE3& T_w_c, int k, bool floor_revealed) {
  map::ClusterSegmentation seg;
  seg.scale = kLabelScale;
  seg.labels.create(240 / kLabelScale, 320 / kLabelScale, CV_8U);
  seg.gamma.assign(7, 1.0);  // 6 depth clusters + the no-depth cluster, all static (Seg.DenseInit = 0)
  seg.pixel_counts.assign(7, 0);
  for (int r = 0; r < seg.labels.rows; ++r) {
    for (int c = 0; c < seg.labels.cols; ++c) {
      const int label = clusterOfPixel(T_w_c, k, c * kLabelScale, r * kLabelScale);
      seg.labels.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(label);
      ++seg.pixel_counts[static_cast<std::size_t>(label)];
    }
  }
  seg.neighbours = {{2, 3}, {2, 4}, {3, 5}, {4, 5}};
  if (k >= kFirstBoxKeyFrame) seg.neighbours.insert(seg.neighbours.end(), {{0, 1}, {0, 4}});  // box on the floor
  // The floor quadrant revealed in the last keyframe touches only the box (in space), as a strip of
  // floor beside a box that fills the view.
  if (floor_revealed) seg.neighbours = {{0, 1}, {0, 4}, {1, 4}, {2, 3}, {3, 5}};
  seg.depth_scale = kDepthScale;
  seg.depth_mm.create(240 / kDepthScale, 320 / kDepthScale, CV_16U);
  for (int r = 0; r < seg.depth_mm.rows; ++r) {
    for (int c = 0; c < seg.depth_mm.cols; ++c) {
      const double u = c * kDepthScale, v = r * kDepthScale;
      double depth = sphereDepth(T_w_c, u, v);
      if (k >= kFirstBoxKeyFrame && boxAt(k).contains(camera().backProject(Vec2(u, v), 10.0))) depth = kBoxDepth_m;
      seg.depth_mm.at<std::uint16_t>(r, c) = static_cast<std::uint16_t>(std::lround(1000.0 * depth));
    }
  }
  return seg;
}

struct Window {
  map::Map map;
  Scene scene;
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;
  std::vector<std::shared_ptr<map::MapPoint>> static_points;
  std::vector<std::shared_ptr<map::MapPoint>> box_points;
  std::vector<std::shared_ptr<map::MapPoint>> revealed_points;  ///< made by the last keyframe alone (floor_revealed)
};

/// The map of the window, as tracking would have left it: poses from kf2 on dragged by the box
/// (3.5 cm, 0.6 deg), points created from their first keyframe's measured depth at that pose.
/// With floor_revealed, the background the last keyframe sees in its lower-left quadrant (cluster 4)
/// was hidden from every earlier keyframe: its points are made from the last keyframe's depth alone.
std::unique_ptr<Window> makeWindow(bool floor_revealed = false) {
  auto window = std::make_unique<Window>();
  std::mt19937 rng(41);
  window->scene = makeScene(rng);
  const Scene& scene = window->scene;
  std::normal_distribution<double> pixel_noise(0.0, 0.5);
  std::uniform_int_distribution<std::uint64_t> bits;
  const imu::test::AnalyticTrajectory trajectory;
  const SE3 T_b_c = bodyToCamera();
  std::vector<int> static_index(scene.static_w.size(), -1);  // map point index per static point
  window->box_points.resize(scene.box_local.size());
  std::vector<bool> hidden_before_last(scene.static_w.size(), false);
  if (floor_revealed) {
    const SE3 T_w_c_last = scene.T_w_b_true.back() * T_b_c;
    for (std::size_t j = 0; j < scene.static_w.size(); ++j) {
      const Vec3 p_c = T_w_c_last.inverse() * scene.static_w[j];
      if (p_c.z() < 0.5 || boxAt(kNumKeyFrames - 1).contains(p_c)) continue;
      const Vec2 uv = camera().project(p_c);
      hidden_before_last[j] = camera().isInImage(uv) &&
                              clusterOfPixel(T_w_c_last, kNumKeyFrames - 1, uv.x(), uv.y()) == 4;
    }
  }
  for (int k = 0; k < kNumKeyFrames; ++k) {
    const SE3 T_w_c_true = scene.T_w_b_true[static_cast<std::size_t>(k)] * T_b_c;
    // Keypoints: visible static points, then (kf2 on) the box's points.
    features::OrbFeatures features;
    std::vector<float> depths;
    std::vector<std::pair<bool, int>> source;  // (box point, index)
    auto add_keypoint = [&](const Vec3& p_c, bool box, int index) {
      const Vec2 uv = camera().project(p_c) + Vec2(pixel_noise(rng), pixel_noise(rng));
      if (uv.x() < 5.0 || uv.y() < 5.0 || uv.x() > 314.0 || uv.y() > 234.0) return;
      features::Keypoint kp;
      kp.x_px = static_cast<float>(uv.x());
      kp.y_px = static_cast<float>(uv.y());
      features.keypoints.push_back(kp);
      features.descriptors.push_back({bits(rng), bits(rng), bits(rng), bits(rng)});
      depths.push_back(static_cast<float>(p_c.z() + 0.001 * p_c.z() * p_c.z() * pixel_noise(rng)));
      source.emplace_back(box, index);
    };
    for (std::size_t j = 0; j < scene.static_w.size(); ++j) {
      const Vec3 p_c = T_w_c_true.inverse() * scene.static_w[j];
      if (p_c.z() < 0.5 || (k >= kFirstBoxKeyFrame && boxAt(k).contains(p_c))) continue;
      if (hidden_before_last[j] && k < kNumKeyFrames - 1) continue;
      add_keypoint(p_c, false, static_cast<int>(j));
    }
    if (k >= kFirstBoxKeyFrame) {
      const Box box = boxAt(k);
      for (std::size_t n = 0; n < scene.box_local.size(); ++n) {
        const Vec2& xy = scene.box_local[n];
        add_keypoint(Vec3(xy.x() + box.x_min + 0.5, xy.y(), kBoxDepth_m), true, static_cast<int>(n));
      }
    }
    map::Frame frame(1.0 + kSpacing_s * k, camera(), T_b_c, std::move(features), std::move(depths), scaleFactors());
    frame.setSegmentation(segmentationOf(T_w_c_true, k, floor_revealed && k == kNumKeyFrames - 1), 0.5);
    SE3 T_w_b = scene.T_w_b_true[static_cast<std::size_t>(k)];
    if (k >= kFirstBoxKeyFrame) {
      T_w_b = SE3(T_w_b.quaternion() * so3ExpQuat(Vec3(0.0, 0.0, 0.01)), T_w_b.translation() + Vec3(0.02, -0.02, 0.02));
    }
    frame.setPose_T_w_b(T_w_b);
    frame.setVelocity(scene.v_w_b_true[static_cast<std::size_t>(k)]);
    std::shared_ptr<map::KeyFrame> kf = window->map.createKeyFrame(frame);
    if (k > 0) {
      imu::Preintegrated pim(imu::ImuBias{}, imu::ImuNoise());
      pim.integrate(trajectory.samples(1.0 + kSpacing_s * (k - 1), 1.0 + kSpacing_s * k, 200.0));
      kf->setPreviousKeyFrame(window->keyframes.back()->id());
      window->keyframes.back()->setNextKeyFrame(kf->id());
      kf->setImuFromPrevious(pim);
    }
    for (int i = 0; i < kf->numKeypoints(); ++i) {
      const auto [box, index] = source[static_cast<std::size_t>(i)];
      std::shared_ptr<map::MapPoint> point;
      if (box) {
        point = window->box_points[static_cast<std::size_t>(index)];
      } else if (static_index[static_cast<std::size_t>(index)] >= 0) {
        point = window->static_points[static_cast<std::size_t>(static_index[static_cast<std::size_t>(index)])];
      }
      if (!point) {  // first sighting: created from this keyframe's depth at its (estimated) pose
        point = window->map.createMapPoint(kf->T_w_c() * kf->p_c(i), kf->id());
        if (box) {
          window->box_points[static_cast<std::size_t>(index)] = point;
        } else {
          static_index[static_cast<std::size_t>(index)] = static_cast<int>(window->static_points.size());
          window->static_points.push_back(point);
          if (hidden_before_last[static_cast<std::size_t>(index)]) window->revealed_points.push_back(point);
        }
      }
      EXPECT_TRUE(window->map.addObservation(*kf, i, *point)) << "kf " << k << " keypoint " << i;
    }
    window->keyframes.push_back(kf);
  }
  for (const auto& points : {window->static_points, window->box_points}) {
    for (const auto& point : points) {
      if (point) window->map.updateNormalAndDistances(*point);
    }
  }
  for (const auto& kf : window->keyframes) window->map.updateConnections(*kf);
  return window;
}

WindowBaOptions windowOptions(bool robust, bool evidence_only = true) {
  WindowBaOptions options;
  options.window_size = kNumKeyFrames - 1;
  options.iterations = 10;
  options.bf_px_m = 262.5 * 0.08;
  options.inertial = true;
  options.g_w = imu::gravityWorld();
  options.robust = robust;
  options.alternations = 3;
  options.evidence_only = evidence_only;
  options.scores.lambda_d = 50.0;
  options.scores.lambda_s = 100.0;
  options.scores.lambda_p = 2.0;
  options.scores.lambda_phi = 0.5;
  options.scores.sweeps = 5;
  return options;
}

double worstTranslationError(const Window& window) {
  double worst = 0.0;
  for (int k = 1; k < kNumKeyFrames; ++k) {
    const SE3& truth = window.scene.T_w_b_true[static_cast<std::size_t>(k)];
    worst = std::max(worst, (window.keyframes[static_cast<std::size_t>(k)]->T_w_b().translation() - truth.translation()).norm());
  }
  return worst;
}

TEST(RobustWindowBa, MovingBoxIsRemovedAndStaticPosesRecovered) {
  const std::unique_ptr<Window> window = makeWindow();
  ASSERT_EQ(window->keyframes.size(), static_cast<std::size_t>(kNumKeyFrames));
  const WindowBaStats stats =
      localWindowBundleAdjust(window->map, window->keyframes.back(), windowOptions(true), levelSigma2());
  EXPECT_EQ(stats.optimised_keyframes, kNumKeyFrames - 1);
  EXPECT_EQ(stats.score_steps, 4);  // one at the initial states, one after each state step

  // Static poses to the noise level (0.5 px keypoints, ~150 points per keyframe, exact IMU).
  for (int k = 1; k < kNumKeyFrames; ++k) {
    const SE3& truth = window->scene.T_w_b_true[static_cast<std::size_t>(k)];
    const SE3 estimate = window->keyframes[static_cast<std::size_t>(k)]->T_w_b();
    EXPECT_LT((estimate.translation() - truth.translation()).norm(), 0.005) << "kf " << k;
    EXPECT_LT(so3Log(truth.quaternion().conjugate() * estimate.quaternion()).norm() * 180.0 / M_PI, 0.1) << "kf " << k;
  }
  // Every box point ended dynamic (deleted); the static points stay.
  int box_left = 0;
  for (const auto& point : window->box_points) box_left += (point && !point->isBad()) ? 1 : 0;
  EXPECT_EQ(box_left, 0);
  EXPECT_EQ(stats.dynamic_points_erased, static_cast<int>(window->box_points.size()));
  int static_lost = 0;
  for (const auto& point : window->static_points) static_lost += point->isBad() || point->beta() < 0.5 ? 1 : 0;
  EXPECT_LE(static_lost, static_cast<int>(window->static_points.size()) / 100);
  // The box's clusters are dynamic, the background's static, in every optimised keyframe with the box.
  for (int k = kFirstBoxKeyFrame; k < kNumKeyFrames; ++k) {
    const std::vector<double> gamma = window->keyframes[static_cast<std::size_t>(k)]->gamma();
    EXPECT_LT(gamma[0], 0.5) << "kf " << k;
    EXPECT_LT(gamma[1], 0.5) << "kf " << k;
    for (int c = 2; c < 6; ++c) EXPECT_GT(gamma[static_cast<std::size_t>(c)], 0.75) << "kf " << k << " cluster " << c;
    EXPECT_NEAR(gamma[6], 1.0, 1e-12);  // the no-depth cluster stays static
  }
  EXPECT_FALSE(stats.static_set_changed.empty());
}

TEST(RobustWindowBa, PlainVibaStaysDraggedByTheBox) {
  // The same window through the plain VIBA (Mapping.RobustBeta = 0): the box's consistent points
  // outvote the IMU and the background.
  const std::unique_ptr<Window> window = makeWindow();
  localWindowBundleAdjust(window->map, window->keyframes.back(), windowOptions(false), levelSigma2());
  EXPECT_GT(worstTranslationError(*window), 0.01);
  int box_left = 0;
  for (const auto& point : window->box_points) box_left += (point && !point->isBad()) ? 1 : 0;
  EXPECT_GT(box_left, 0);
}

int survivors(const std::vector<std::shared_ptr<map::MapPoint>>& points) {
  int alive = 0;
  for (const auto& point : points) alive += !point->isBad() && point->beta() >= 0.5 ? 1 : 0;
  return alive;
}

TEST(RobustWindowBa, ARevealedClusterWithoutEvidenceKeepsItsScoreAndItsPoints) {
  // The last keyframe sees floor that the box hid from every earlier one (as a keyframe placed at
  // the IMU's prediction after an occlusion does): its points are made from that keyframe's depth
  // alone, no static map point projects there and in space it touches only the box (only the box's
  // old points, in front of it, give Eq. 56 samples). Nothing in the window says the floor moves,
  // so it stays static and keeps its points.
  const std::unique_ptr<Window> window = makeWindow(true);
  ASSERT_GE(window->revealed_points.size(), 15u);
  for (const auto& point : window->revealed_points) ASSERT_EQ(point->numObservations(), 1);
  const WindowBaStats stats =
      localWindowBundleAdjust(window->map, window->keyframes.back(), windowOptions(true), levelSigma2());
  const std::vector<double> gamma = window->keyframes.back()->gamma();
  EXPECT_GT(gamma[4], 0.75);
  EXPECT_LT(gamma[0], 0.5);
  EXPECT_LT(gamma[1], 0.5);
  EXPECT_GE(survivors(window->revealed_points), static_cast<int>(window->revealed_points.size()) * 9 / 10);
  // The box is still found and the static poses still recovered.
  int box_left = 0;
  for (const auto& point : window->box_points) box_left += (point && !point->isBad()) ? 1 : 0;
  EXPECT_EQ(box_left, 0);
  EXPECT_LT(worstTranslationError(*window), 0.005);
  EXPECT_GE(stats.dynamic_points_erased, static_cast<int>(window->box_points.size()));
}

TEST(RobustWindowBa, WithoutTheEvidenceRuleTheBoxDragsARevealedClusterAndDeletesItsPoints) {
  // LocalMapping.ScoresNeedEvidence = 0 on the same window: Eq. 54's smoothness with the box pulls
  // the floor's score towards the box's, and Eq. 57 then deletes the floor's points.
  const std::unique_ptr<Window> window = makeWindow(true);
  localWindowBundleAdjust(window->map, window->keyframes.back(), windowOptions(true, false), levelSigma2());
  EXPECT_LT(window->keyframes.back()->gamma()[4], 0.75);
  EXPECT_LT(survivors(window->revealed_points), static_cast<int>(window->revealed_points.size()) / 2);
}

}  // namespace
}  // namespace ltlo::mapping
