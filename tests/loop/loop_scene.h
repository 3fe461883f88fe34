#pragma once
// The synthetic lap of the loop-closing tests (no images, fixed seeds): a camera on a circle
// looking out at a wall of landmarks (each with its own random descriptor, a vocabulary trained on
// them), keyframes built as tracking and local mapping would (pose from the previous keyframe's
// current pose and the true motion with a drift error, points created from depth, a landmark keeps
// its point while consecutive keyframes see it).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <optional>
#include <random>
#include <unordered_map>
#include <utility>
#include <vector>

#include "bow/vocabulary.h"
#include "ltlo/map/atlas.h"

namespace ltlo::loop::test {

inline constexpr int kStepsPerLap = 24;
inline constexpr int kNumLandmarks = 1500;
inline constexpr double kCircleRadius_m = 2.0;
inline const PinholeCamera kCamera(525.0, 525.0, 319.5, 239.5, 640, 480);

/// Camera (= body) on the circle at step k, optical axis pointing outwards, y down.
inline SE3 truePose_T_w_b(int k) {
  const double a = 2.0 * M_PI * k / kStepsPerLap;
  Mat3 R_w_c;
  R_w_c.col(0) = Vec3(std::sin(a), -std::cos(a), 0.0);
  R_w_c.col(1) = Vec3(0.0, 0.0, -1.0);
  R_w_c.col(2) = Vec3(std::cos(a), std::sin(a), 0.0);
  return SE3(R_w_c, Vec3(kCircleRadius_m * std::cos(a), kCircleRadius_m * std::sin(a), 0.0));
}

struct World {
  std::vector<Vec3> p_w;
  std::vector<features::Descriptor> descriptors;
  std::unique_ptr<bow::Vocabulary> vocabulary;
};

/// Landmarks visible from T_w_c with their camera-frame positions.
inline std::vector<std::pair<int, Vec3>> visibleLandmarks(const World& world, const SE3& T_w_c) {
  std::vector<std::pair<int, Vec3>> visible;
  const SE3 T_c_w = T_w_c.inverse();
  for (int i = 0; i < kNumLandmarks; ++i) {
    const Vec3 p_c = T_c_w * world.p_w[static_cast<std::size_t>(i)];
    if (p_c.z() < 0.5) continue;
    const Vec2 uv = kCamera.project(p_c);
    if (uv.x() < 10.0 || uv.x() > 629.0 || uv.y() < 10.0 || uv.y() > 469.0) continue;
    visible.emplace_back(i, p_c);
  }
  return visible;
}

inline const World& world() {
  static const World w = [] {
    World out;
    std::mt19937 rng(41);
    std::uniform_real_distribution<double> angle(0.0, 2.0 * M_PI), radius(4.5, 6.0), height(-1.2, 1.2);
    std::uniform_int_distribution<std::uint64_t> bits;
    for (int i = 0; i < kNumLandmarks; ++i) {
      const double a = angle(rng), r = radius(rng);
      out.p_w.emplace_back(r * std::cos(a), r * std::sin(a), height(rng));
      out.descriptors.push_back({bits(rng), bits(rng), bits(rng), bits(rng)});
    }
    // Training images: what each keyframe of a lap sees (IDF weights of the words).
    std::vector<std::vector<features::Descriptor>> images;
    for (int k = 0; k < kStepsPerLap; ++k) {
      images.emplace_back();
      for (const auto& [i, p_c] : visibleLandmarks(out, truePose_T_w_b(k))) {
        images.back().push_back(out.descriptors[static_cast<std::size_t>(i)]);
      }
    }
    out.vocabulary = std::make_unique<bow::Vocabulary>(bow::Vocabulary::train(images, bow::TrainOptions{10, 3, 5, 1, 1, 0, {}}));
    return out;
  }();
  return w;
}

/// Builds keyframes into an Atlas as tracking + local mapping would.
class SceneBuilder {
 public:
  SceneBuilder(map::Atlas& atlas, const SE3& step_error) : atlas_(atlas), step_error_(step_error) {}

  /// The keyframe at true place `step`. The first one is at `T_w_b_first` in its map (the map's
  /// world frame), by default its true pose.
  std::shared_ptr<map::KeyFrame> add(int step, const std::optional<SE3>& T_w_b_first = std::nullopt) {
    const World& w = world();
    const SE3 T_w_b_true = truePose_T_w_b(step);
    const SE3 T_w_b_estimate =
        kfs_.empty() ? T_w_b_first.value_or(T_w_b_true)
                     : kfs_.back()->T_w_b() * truePose_T_w_b(steps_.back()).inverse() * T_w_b_true * step_error_;
    std::vector<std::pair<int, Vec3>> visible = visibleLandmarks(w, T_w_b_true);
    if (view_columns_px_) {
      // Only a strip of the image is visible (the rest covered, e.g. by a box in front).
      std::vector<std::pair<int, Vec3>> kept;
      for (const auto& landmark : visible) {
        const double u = kCamera.project(landmark.second).x();
        if (u >= view_columns_px_->first && u <= view_columns_px_->second) kept.push_back(landmark);
      }
      visible = std::move(kept);
    }
    features::OrbFeatures features;
    std::vector<float> depths;
    for (const auto& [i, p_c] : visible) {
      const Vec2 uv = kCamera.project(p_c);
      features::Keypoint kp;
      kp.x_px = static_cast<float>(uv.x());
      kp.y_px = static_cast<float>(uv.y());
      features.keypoints.push_back(kp);
      features.descriptors.push_back(w.descriptors[static_cast<std::size_t>(i)]);
      depths.push_back(static_cast<float>(p_c.z()));
    }
    map::Frame frame(0.5 * static_cast<double>(kfs_.size()), kCamera, SE3(), std::move(features), std::move(depths),
                     {1.0f, 1.2f, 1.44f, 1.728f});
    frame.setPose_T_w_b(T_w_b_estimate);
    frame.computeBow(*w.vocabulary);
    map::Map& map = kfs_.empty() ? atlas_.activeMap() : *atlas_.map(kfs_.back()->mapId());
    const std::shared_ptr<map::KeyFrame> kf = map.createKeyFrame(frame);
    std::unordered_map<int, int> keypoint_of;
    for (std::size_t j = 0; j < visible.size(); ++j) {
      const int landmark = visible[j].first;
      const int keypoint = static_cast<int>(j);
      keypoint_of[landmark] = keypoint;
      // Tracked from the previous keyframe when it saw the landmark, else a new point from depth.
      std::shared_ptr<map::MapPoint> point;
      const auto previous = previous_keypoint_.find(landmark);
      if (previous != previous_keypoint_.end()) point = map.mapPoint(kfs_.back()->mapPoint(previous->second));
      if (!point || point->isBad() || !map.addObservation(*kf, keypoint, *point)) {
        point = map.createMapPoint(T_w_b_estimate * visible[j].second, kf->id());
        EXPECT_TRUE(map.addObservation(*kf, keypoint, *point));
      }
      map.updateDescriptor(*point);  // as local mapping does (projection searches compare it)
    }
    map.updateConnections(*kf);
    previous_keypoint_ = std::move(keypoint_of);
    kfs_.push_back(kf);
    steps_.push_back(step);
    return kf;
  }

  const std::vector<std::shared_ptr<map::KeyFrame>>& keyFrames() const { return kfs_; }
  /// Keyframes added from now on see only the image columns [first, second] (px).
  void restrictView(double first_px, double second_px) { view_columns_px_ = std::make_pair(first_px, second_px); }
  const std::vector<int>& steps() const { return steps_; }

 private:
  map::Atlas& atlas_;
  SE3 step_error_;
  std::vector<std::shared_ptr<map::KeyFrame>> kfs_;
  std::vector<int> steps_;
  std::unordered_map<int, int> previous_keypoint_;  ///< landmark -> keypoint of the last keyframe
  std::optional<std::pair<double, double>> view_columns_px_;
};

/// Per step: yaw (about the camera's y axis) and a translation error.
inline SE3 driftStep() { return SE3::exp((Vec6() << 0.002, 0.008, 0.002, 0.012, 0.004, 0.010).finished()); }

}  // namespace ltlo::loop::test
