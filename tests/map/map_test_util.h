#pragma once
// Generated keyframes and shared map points for the map tests (no images, fixed seeds).
#include <memory>
#include <random>
#include <vector>

#include "ltlo/map/frame.h"
#include "ltlo/map/map.h"

namespace ltlo::map::test {

inline PinholeCamera vgaCamera() { return PinholeCamera(525.0, 525.0, 319.5, 239.5, 640, 480); }
inline std::vector<float> scaleFactors() { return {1.0f, 1.2f, 1.44f, 1.728f}; }

/// A frame of `num_keypoints` random keypoints, descriptors and depths in [1, 4] m, posed at T_w_b.
inline Frame randomFrame(std::mt19937& rng, double t_s, const SE3& T_w_b, int num_keypoints = 200) {
  std::uniform_real_distribution<float> x(0.0f, 639.0f), y(0.0f, 479.0f), depth(1.0f, 4.0f);
  std::uniform_int_distribution<int> octave(0, 3);
  std::uniform_int_distribution<std::uint64_t> bits;
  features::OrbFeatures features;
  std::vector<float> depths;
  for (int i = 0; i < num_keypoints; ++i) {
    features::Keypoint kp;
    kp.x_px = x(rng);
    kp.y_px = y(rng);
    kp.octave = octave(rng);
    features.keypoints.push_back(kp);
    features.descriptors.push_back({bits(rng), bits(rng), bits(rng), bits(rng)});
    depths.push_back(depth(rng));
  }
  Frame frame(t_s, vgaCamera(), SE3(), std::move(features), std::move(depths), scaleFactors());
  frame.setPose_T_w_b(T_w_b);
  return frame;
}

/// Builds keyframes and points shared between chosen keyframes, handing out each keyframe's
/// keypoints in order so every observation uses a fresh keypoint.
class SceneBuilder {
 public:
  SceneBuilder(Map& map, unsigned seed) : map_(map), rng_(seed) {}

  std::shared_ptr<KeyFrame> addKeyFrame(const SE3& T_w_b = SE3(), int num_keypoints = 200) {
    std::shared_ptr<KeyFrame> kf = map_.createKeyFrame(randomFrame(rng_, t_s_, T_w_b, num_keypoints));
    t_s_ += 0.1;
    next_keypoint_[kf->id()] = 0;
    return kf;
  }

  /// `count` new points, each observed by every keyframe of `kfs`.
  std::vector<std::shared_ptr<MapPoint>> share(const std::vector<std::shared_ptr<KeyFrame>>& kfs, int count) {
    std::uniform_real_distribution<double> coord(-2.0, 2.0);
    std::vector<std::shared_ptr<MapPoint>> points;
    for (int n = 0; n < count; ++n) {
      std::shared_ptr<MapPoint> point =
          map_.createMapPoint(Vec3(coord(rng_), coord(rng_), 3.0 + coord(rng_)), KeyFrameId());
      for (const std::shared_ptr<KeyFrame>& kf : kfs) {
        const int index = next_keypoint_[kf->id()]++;
        if (!map_.addObservation(*kf, index, *point)) throw std::logic_error("observation refused");
      }
      points.push_back(point);
    }
    return points;
  }

  std::mt19937& rng() { return rng_; }

 private:
  Map& map_;
  std::mt19937 rng_;
  double t_s_ = 0.0;
  std::unordered_map<KeyFrameId, int> next_keypoint_;
};

}  // namespace ltlo::map::test
