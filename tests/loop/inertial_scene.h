#pragma once
// Generated visual-inertial maps for the loop-closing tests (no images, fixed seeds): keyframes on
// the analytic IMU trajectory (tests/common) linked by their preintegrations (exact 200 Hz readings
// with a constant bias, integrated at zero bias as tracking does before the IMU is initialised),
// world points with their own descriptors seen from the true poses (exact pixels and depths), map
// points created from the keyframes' estimated poses as tracking would.
#include <functional>
#include <memory>
#include <random>
#include <unordered_map>
#include <vector>

#include "common/analytic_trajectory.h"
#include "ltlo/map/map.h"

namespace ltlo::loop::test {

inline const PinholeCamera& sceneCamera() {
  static const PinholeCamera camera(525.0, 525.0, 319.5, 239.5, 640, 480);
  return camera;
}

/// Camera along the body x axis, a few cm off the IMU.
inline SE3 sceneT_b_c() {
  Mat3 R_b_c;
  R_b_c << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return SE3(R_b_c, Vec3(0.05, -0.02, 0.01));
}

inline imu::ImuBias sceneBias() { return imu::ImuBias{Vec3(0.003, -0.002, 0.004), Vec3(0.04, -0.03, 0.05)}; }

/// The world: points seen from the trajectory, each with a random descriptor.
struct SceneWorld {
  imu::test::AnalyticTrajectory trajectory;
  std::vector<Vec3> p_w;
  std::vector<features::Descriptor> descriptors;

  SE3 T_w_b(double t_s) const {
    const imu::NavState s = trajectory.state(t_s);
    return SE3(s.R_w_b, s.p_w_b);
  }
  /// `per_keyframe` points in front of the camera at each time in `times` (1.5-4 m).
  void addPointsSeenAt(const std::vector<double>& times, int per_keyframe, std::mt19937& rng) {
    std::uniform_real_distribution<double> u(20.0, 620.0), v(20.0, 460.0), depth(1.5, 4.0);
    std::uniform_int_distribution<std::uint64_t> bits;
    for (const double t : times) {
      const SE3 T_w_c = T_w_b(t) * sceneT_b_c();
      for (int n = 0; n < per_keyframe; ++n) {
        p_w.push_back(T_w_c * sceneCamera().backProject(Vec2(u(rng), v(rng)), depth(rng)));
        descriptors.push_back({bits(rng), bits(rng), bits(rng), bits(rng)});
      }
    }
  }
};

/// Keyframes of one map, in time order.
struct SceneMap {
  std::vector<std::shared_ptr<map::KeyFrame>> kfs;
  std::vector<double> times;
};

/// Builds keyframes at `times` into `map`, each at the estimated pose `estimate(k, T_w_b_true)`,
/// with velocity `velocity(k, v_w_b_true)` and bias `bias(k)`; consecutive keyframes are linked by
/// their preintegration. `vocabulary` (may be null) gives every keyframe its BoW.
inline SceneMap buildSceneMap(map::Map& map, const SceneWorld& world, const std::vector<double>& times,
                              const std::function<SE3(int, const SE3&)>& estimate,
                              const std::function<Vec3(int, const Vec3&)>& velocity,
                              const std::function<imu::ImuBias(int)>& bias, const bow::Vocabulary* vocabulary = nullptr) {
  SceneMap out;
  out.times = times;
  const SE3 T_b_c = sceneT_b_c();
  std::unordered_map<int, std::shared_ptr<map::MapPoint>> point_of;  // world point -> map point
  for (std::size_t k = 0; k < times.size(); ++k) {
    const double t = times[k];
    const SE3 T_w_b_true = world.T_w_b(t);
    const SE3 T_c_w_true = (T_w_b_true * T_b_c).inverse();
    features::OrbFeatures features;
    std::vector<float> depths;
    std::vector<int> seen;
    for (std::size_t i = 0; i < world.p_w.size(); ++i) {
      const Vec3 p_c = T_c_w_true * world.p_w[i];
      if (p_c.z() < 0.3) continue;
      const Vec2 uv = sceneCamera().project(p_c);
      if (uv.x() < 5.0 || uv.x() > 634.0 || uv.y() < 5.0 || uv.y() > 474.0) continue;
      features::Keypoint kp;
      kp.x_px = static_cast<float>(uv.x());
      kp.y_px = static_cast<float>(uv.y());
      features.keypoints.push_back(kp);
      features.descriptors.push_back(world.descriptors[i]);
      depths.push_back(static_cast<float>(p_c.z()));
      seen.push_back(static_cast<int>(i));
    }
    map::Frame frame(t, sceneCamera(), T_b_c, std::move(features), std::move(depths), {1.0f, 1.2f, 1.44f, 1.728f});
    const int index = static_cast<int>(k);
    frame.setPose_T_w_b(estimate(index, T_w_b_true));
    frame.setVelocity(velocity(index, world.trajectory.velocity(t)));
    frame.setBias(bias(index));
    if (k > 0) {
      imu::Preintegrated pim{imu::ImuBias(), imu::ImuNoise()};
      pim.integrate(world.trajectory.samples(times[k - 1], t, 200.0, sceneBias()));
      frame.imu_from_last_keyframe = pim;
    }
    if (vocabulary != nullptr) frame.computeBow(*vocabulary);
    const std::shared_ptr<map::KeyFrame> kf = map.createKeyFrame(frame);
    for (std::size_t j = 0; j < seen.size(); ++j) {
      const int keypoint = static_cast<int>(j);
      std::shared_ptr<map::MapPoint>& point = point_of[seen[j]];
      if (!point) point = map.createMapPoint(kf->T_w_c() * kf->p_c(keypoint), kf->id());
      map.addObservation(*kf, keypoint, *point);
    }
    map.updateConnections(*kf);
    if (!out.kfs.empty()) {
      kf->setPreviousKeyFrame(out.kfs.back()->id());
      out.kfs.back()->setNextKeyFrame(kf->id());
    }
    out.kfs.push_back(kf);
  }
  for (const auto& [world_index, point] : point_of) {
    map.updateDescriptor(*point);
    map.updateNormalAndDistances(*point);
  }
  return out;
}

inline std::vector<double> sceneTimes(int count, double t0_s = 0.5, double spacing_s = 0.3) {
  std::vector<double> times;
  for (int k = 0; k < count; ++k) times.push_back(t0_s + spacing_s * k);
  return times;
}

}  // namespace ltlo::loop::test
