// Loop closing with the IMU initialised (issue 10) on generated visual-inertial maps
// (inertial_scene.h): the visual-inertial full BA recovers perturbed poses, velocities and biases,
// and a merge with a 4-DoF alignment keeps gravity (roll and pitch of the merged map) and closes
// the gap where an SE3 alignment tilts the merged map.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <tuple>
#include <utility>

#include "bow/vocabulary.h"
#include "inertial_scene.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/loop/global_ba.h"
#include "ltlo/loop/map_merger.h"
#include "ltlo/map/atlas.h"

namespace ltlo::loop {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

double angleDeg(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)) * kRadToDeg; }
/// Tilt of a body pose: its up axis in the body frame (roll and pitch relative to gravity).
Vec3 upInBody(const SE3& T_w_b) { return T_w_b.rotationMatrix().transpose() * Vec3(0.0, 0.0, 1.0); }

TEST(GlobalBundleAdjustment, VisualInertialRecoversPosesVelocitiesAndBiases) {
  std::mt19937 rng(51);
  std::normal_distribution<double> normal(0.0, 1.0);
  test::SceneWorld world;
  const std::vector<double> times = test::sceneTimes(10);
  world.addPointsSeenAt(times, 40, rng);
  map::Map map;
  // Tracking-like estimates: 2 cm / 0.5 deg pose errors (not on the origin), velocities 0.1 m/s
  // off, biases unknown (zero); the origin's velocity is off too (only its pose is the gauge).
  std::vector<SE3> T_estimate;
  for (std::size_t k = 0; k < times.size(); ++k) {
    const SE3 T_true = world.T_w_b(times[k]);
    T_estimate.push_back(k == 0 ? T_true
                                : SE3(T_true.quaternion() * so3ExpQuat((0.5 / kRadToDeg) * Vec3(normal(rng), normal(rng), normal(rng))),
                                      T_true.translation() + 0.02 * Vec3(normal(rng), normal(rng), normal(rng))));
  }
  const test::SceneMap scene = test::buildSceneMap(
      map, world, times, [&](int k, const SE3&) { return T_estimate[static_cast<std::size_t>(k)]; },
      [](int, const Vec3& v_true) -> Vec3 { return v_true + Vec3(0.1, -0.1, 0.05); },
      [](int) { return imu::ImuBias(); });

  auto errors = [&] {
    struct {
      double position_m = 0.0, rotation_deg = 0.0, velocity_m_s = 0.0, b_g = 0.0, b_a = 0.0;
    } e;
    for (std::size_t k = 0; k < scene.kfs.size(); ++k) {
      const map::KeyFrame& kf = *scene.kfs[k];
      const SE3 T_true = world.T_w_b(times[k]);
      e.position_m = std::max(e.position_m, (kf.T_w_b().translation() - T_true.translation()).norm());
      e.rotation_deg = std::max(e.rotation_deg, so3Log(kf.T_w_b().quaternion().conjugate() * T_true.quaternion()).norm() * kRadToDeg);
      e.velocity_m_s = std::max(e.velocity_m_s, (kf.v_w_b() - world.trajectory.velocity(times[k])).norm());
      e.b_g = std::max(e.b_g, (kf.bias().b_g - test::sceneBias().b_g).norm());
      e.b_a = std::max(e.b_a, (kf.bias().b_a - test::sceneBias().b_a).norm());
    }
    return e;
  };
  const auto before = errors();
  GlobalBaOptions options;
  options.g_w = imu::gravityWorld();
  const GlobalBaSolution solution = optimizeGlobalBundleAdjustment(map, options);
  ASSERT_TRUE(solution.valid);
  applyGlobalBundleAdjustment(map, solution);
  const auto after = errors();
  std::printf("[ VI GBA   ] %d keyframes, %d points, %d inertial links: max errors position %.4f -> %.5f m, rotation "
              "%.3f -> %.4f deg, velocity %.3f -> %.4f m/s, b_g %.5f -> %.5f rad/s, b_a %.4f -> %.4f m/s^2\n",
              solution.result.keyframes, solution.result.points, solution.result.inertial_links, before.position_m,
              after.position_m, before.rotation_deg, after.rotation_deg, before.velocity_m_s, after.velocity_m_s,
              before.b_g, after.b_g, before.b_a, after.b_a);
  EXPECT_EQ(solution.result.inertial_links, static_cast<int>(times.size()) - 1);
  // Exact pixels, depths and readings: what is left is the first-order bias correction of the
  // preintegrations (integrated at zero bias) and the solver's tolerance.
  EXPECT_LT(after.position_m, 1e-3);
  EXPECT_LT(after.rotation_deg, 0.02);
  EXPECT_LT(after.velocity_m_s, 0.01);
  EXPECT_LT(after.b_g, 5e-4);
  EXPECT_LT(after.b_a, 0.01);
  EXPECT_GT(before.velocity_m_s, 0.1);
}

// Loop.FullBaGravity: the full BA started from a gravity 0.58 deg off (as an IMU initialisation over
// a short or occluded window leaves it) turns it back to the truth; held fixed, the tilt goes into
// the poses and biases instead.
TEST(GlobalBundleAdjustment, VisualInertialEstimatesTheGravityDirection) {
  const Vec3 g_true = imu::gravityWorld();
  const Vec3 g_start = so3Exp(Vec3(0.5 / kRadToDeg, -0.3 / kRadToDeg, 0.0)) * g_true;
  struct Outcome {
    double position_m = 0.0, b_a = 0.0, gravity_error_deg = 0.0, turned_deg = 0.0;
  };
  auto run = [&](bool estimate_gravity) {
    std::mt19937 rng(57);
    std::normal_distribution<double> normal(0.0, 1.0);
    test::SceneWorld world;
    const std::vector<double> times = test::sceneTimes(16);
    world.addPointsSeenAt(times, 40, rng);
    map::Map map;
    std::vector<SE3> T_estimate;
    for (std::size_t k = 0; k < times.size(); ++k) {
      const SE3 T_true = world.T_w_b(times[k]);
      T_estimate.push_back(k == 0 ? T_true : SE3(T_true.quaternion(), T_true.translation() + 0.02 * Vec3(normal(rng), normal(rng), normal(rng))));
    }
    const test::SceneMap scene = test::buildSceneMap(
        map, world, times, [&](int k, const SE3&) { return T_estimate[static_cast<std::size_t>(k)]; },
        [](int, const Vec3& v_true) { return v_true; }, [](int) { return imu::ImuBias(); });
    GlobalBaOptions options;
    options.g_w = g_start;
    options.estimate_gravity = estimate_gravity;
    options.iterations = 20;
    const GlobalBaSolution solution = optimizeGlobalBundleAdjustment(map, options);
    EXPECT_TRUE(solution.valid);
    applyGlobalBundleAdjustment(map, solution);
    Outcome outcome;
    for (std::size_t k = 0; k < scene.kfs.size(); ++k) {
      const map::KeyFrame& kf = *scene.kfs[k];
      outcome.position_m = std::max(outcome.position_m, (kf.T_w_b().translation() - world.T_w_b(times[k]).translation()).norm());
      outcome.b_a = std::max(outcome.b_a, (kf.bias().b_a - test::sceneBias().b_a).norm());
    }
    EXPECT_EQ(solution.g_w_after.has_value(), estimate_gravity);
    outcome.gravity_error_deg = angleDeg(solution.g_w_after.value_or(g_start), g_true);
    outcome.turned_deg = solution.result.gravity_change_deg;
    return outcome;
  };
  const Outcome held = run(false);
  const Outcome estimated = run(true);
  std::printf("[ VI GBA g ] gravity 0.58 deg off held: max position error %.4f m, b_a error %.4f m/s^2; estimated: "
              "%.5f m, %.4f m/s^2, gravity %.4f deg off (turned by %.3f deg)\n",
              held.position_m, held.b_a, estimated.position_m, estimated.b_a, estimated.gravity_error_deg,
              estimated.turned_deg);
  EXPECT_NEAR(held.gravity_error_deg, angleDeg(g_start, g_true), 1e-9);
  EXPECT_LT(estimated.gravity_error_deg, 0.05);
  EXPECT_NEAR(estimated.turned_deg, angleDeg(g_start, g_true), 0.05);
  EXPECT_LT(estimated.b_a, 0.5 * held.b_a);
  EXPECT_LT(estimated.position_m, 2e-3);
}

// ---- merging two maps of the same place ----

struct MergeScene {
  map::Atlas atlas{100000};
  test::SceneWorld world;
  std::unique_ptr<bow::Vocabulary> vocabulary;
  test::SceneMap old_side;
  test::SceneMap new_side;
  std::vector<Vec3> up_before;  ///< new side's tilts before the merge
};

constexpr int kMergeKeyFrames = 14;

/// The old map at the true poses; the new one (started after a loss at a predicted pose) drives the
/// same path again, its world off by 12 deg of yaw about gravity and 0.4 m; its last keyframe is
/// also tilted by 1 deg about a horizontal axis (as a last tracked pose can be), which the place
/// match sees.
void buildMergeScene(MergeScene& scene) {
  std::mt19937 rng(53);
  const std::vector<double> times = test::sceneTimes(kMergeKeyFrames);
  scene.world.addPointsSeenAt(times, 40, rng);
  std::vector<std::vector<features::Descriptor>> training{scene.world.descriptors};
  std::uniform_int_distribution<std::uint64_t> bits;
  for (int image = 0; image < 4; ++image) {
    training.emplace_back();
    for (int i = 0; i < 200; ++i) training.back().push_back({bits(rng), bits(rng), bits(rng), bits(rng)});
  }
  scene.vocabulary = std::make_unique<bow::Vocabulary>(bow::Vocabulary::train(training, bow::TrainOptions{8, 3, 5, 1, 1, 0, {}}));
  map::Map& old_map = scene.atlas.activeMap();
  scene.old_side = test::buildSceneMap(
      old_map, scene.world, times, [](int, const SE3& T) { return T; }, [](int, const Vec3& v) { return v; },
      [](int) { return test::sceneBias(); }, scene.vocabulary.get());
  map::Map& new_map = scene.atlas.createNewMap();
  const SE3 T_off(so3ExpQuat(Vec3(0.0, 0.0, 12.0 / kRadToDeg)), Vec3(0.4, -0.3, 0.05));
  const Quat tilt = so3ExpQuat(Vec3(1.0 / kRadToDeg, 0.0, 0.0));  // about a horizontal world axis
  scene.new_side = test::buildSceneMap(
      new_map, scene.world, times,
      [&](int k, const SE3& T) {
        const SE3 moved = T_off * T;
        return k == kMergeKeyFrames - 1 ? SE3(tilt * moved.quaternion(), moved.translation()) : moved;
      },
      [&](int, const Vec3& v) -> Vec3 { return T_off.rotationMatrix() * v; }, [](int) { return test::sceneBias(); },
      scene.vocabulary.get());
  for (const auto& kf : scene.new_side.kfs) scene.up_before.push_back(upInBody(kf->T_w_b()));
}

struct MergeErrors {
  double position_m = 0.0;   ///< max over the new side, against the truth (the old map's world)
  double velocity_m_s = 0.0;
  double tilt_deg = 0.0;     ///< max roll/pitch error against the truth (all but the tilted last)
  double tilt_change_outside_deg = 0.0;  ///< max tilt change of keyframes outside the welding window
};

MergeErrors mergeErrors(const MergeScene& scene, int welding_keyframes) {
  MergeErrors e;
  const int n = static_cast<int>(scene.new_side.kfs.size());
  for (int k = 0; k < n; ++k) {
    const map::KeyFrame& kf = *scene.new_side.kfs[static_cast<std::size_t>(k)];
    const double t = scene.new_side.times[static_cast<std::size_t>(k)];
    e.position_m = std::max(e.position_m, (kf.T_w_b().translation() - scene.world.T_w_b(t).translation()).norm());
    e.velocity_m_s = std::max(e.velocity_m_s, (kf.v_w_b() - scene.world.trajectory.velocity(t)).norm());
    if (k < n - 1) e.tilt_deg = std::max(e.tilt_deg, angleDeg(upInBody(kf.T_w_b()), upInBody(scene.world.T_w_b(t))));
    if (k < n - welding_keyframes) {
      e.tilt_change_outside_deg = std::max(e.tilt_change_outside_deg,
                                           angleDeg(upInBody(kf.T_w_b()), scene.up_before[static_cast<std::size_t>(k)]));
    }
  }
  return e;
}

TEST(MapMerger, FourDofAlignmentKeepsGravityAndClosesTheGap) {
  MergeScene scene;
  buildMergeScene(scene);
  const MergeErrors before = mergeErrors(scene, 10);
  MergeOptions merge;
  merge.g_w = imu::gravityWorld();
  merge.welding_keyframes = 10;
  const std::optional<MergeResult> merged =
      mergeAtPlace(scene.atlas, *scene.new_side.kfs.back(), *scene.old_side.kfs.back(), LoopOptions(), merge);
  ASSERT_TRUE(merged.has_value());
  const MergeErrors after = mergeErrors(scene, merge.welding_keyframes);

  // The same merge with an SE3 alignment carries the last keyframe's tilt into the whole map.
  MergeScene se3_scene;
  buildMergeScene(se3_scene);
  const std::optional<MergeResult> se3_merged = mergeAtPlace(se3_scene.atlas, *se3_scene.new_side.kfs.back(),
                                                             *se3_scene.old_side.kfs.back(), LoopOptions());
  ASSERT_TRUE(se3_merged.has_value());
  const MergeErrors se3 = mergeErrors(se3_scene, merge.welding_keyframes);
  std::printf("[ MERGE4DOF] %d inliers; welding: %d duplicates fused, %d observations added, %d optimised + %d held "
              "keyframes, %d points, %d inertial links, chi2 "
              "%.3g -> %.3g; new side max errors: position %.3f -> %.4f m, velocity %.3f -> %.4f m/s, tilt %.4f -> "
              "%.4f deg (outside the welding window changed %.2e deg); SE3 merge: position %.4f m, tilt %.3f deg\n",
              merged->inliers, merged->welding.fused_points, merged->welding.linked_points,
              merged->welding.optimised_keyframes, merged->welding.fixed_keyframes,
              merged->welding.points, merged->welding.inertial_links, merged->welding.initial_chi2,
              merged->welding.final_chi2, before.position_m, after.position_m, before.velocity_m_s, after.velocity_m_s,
              before.tilt_deg, after.tilt_deg, after.tilt_change_outside_deg, se3.position_m, se3.tilt_deg);
  EXPECT_EQ(scene.atlas.numMaps(), 1u);
  EXPECT_EQ(merged->welding.optimised_keyframes, 2 * merge.welding_keyframes);
  // The new side's own points of the old side's structure around the place become one point each.
  EXPECT_GT(merged->welding.fused_points, 200);
  EXPECT_GT(merged->welding.inertial_links, 2 * merge.welding_keyframes - 4);
  EXPECT_GT(before.position_m, 0.3);
  EXPECT_LT(after.position_m, 0.005);
  EXPECT_LT(after.velocity_m_s, 0.02);
  EXPECT_LT(after.tilt_deg, 0.05);
  EXPECT_LT(after.tilt_change_outside_deg, 1e-6);  // 4-DoF: roll and pitch untouched
  EXPECT_GT(se3.tilt_deg, 0.5);                    // what the 4-DoF alignment avoids
}

// ---- the IMU across a loss (map::MapOrigin::imu_across, bridgeOrigin) ----

// A map started after 0.9 s of loss, placed by the dead reckoning 0.15 m and 1.5 deg (yaw) off in
// its parent's world, merged back where no point of the two is shared (a place matched by a
// strip): only the IMU across the loss ties the two. With that link the full VI BA puts the child
// at the truth; without it the child keeps the dead reckoning's error.
TEST(MapMerger, TheImuAcrossALossTiesTheMapsItSeparated) {
  struct Outcome {
    bool linked = false;
    bool linked_again = false;
    double before_m = 0.0, after_m = 0.0, yaw_after_deg = 0.0;
    int inertial_links = 0;
  };
  auto run = [](bool bridge) {
    Outcome out;
    std::mt19937 rng(61);
    const std::vector<double> times = test::sceneTimes(14);
    test::SceneWorld world;
    world.addPointsSeenAt(times, 40, rng);
    const std::vector<double> parent_times(times.begin(), times.begin() + 6);
    const std::vector<double> child_times(times.begin() + 8, times.end());
    map::Atlas atlas(100000);
    map::Map& parent_map = atlas.activeMap();
    const test::SceneMap parent = test::buildSceneMap(
        parent_map, world, parent_times, [](int, const SE3& T) { return T; }, [](int, const Vec3& v) { return v; },
        [](int) { return test::sceneBias(); });
    map::Map& child_map = atlas.createNewMap();
    const SE3 T_off(so3ExpQuat(Vec3(0.0, 0.0, 1.5 / kRadToDeg)), Vec3(0.12, -0.08, 0.03));
    const test::SceneMap child = test::buildSceneMap(
        child_map, world, child_times, [&](int, const SE3& T) { return T_off * T; },
        [&](int, const Vec3& v) -> Vec3 { return T_off.rotationMatrix() * v; }, [](int) { return test::sceneBias(); });
    map::MapOrigin origin;
    origin.parent = parent_map.id();
    origin.parent_keyframe = parent.kfs.back()->id();
    origin.first_keyframe = child.kfs.front()->id();
    auto across = std::make_shared<imu::Preintegrated>(imu::ImuBias(), imu::ImuNoise());
    across->integrate(world.trajectory.samples(parent_times.back(), child_times.front(), 200.0, test::sceneBias()));
    origin.imu_across = across;
    child_map.setOrigin(origin);
    atlas.mergeMaps(child_map.id(), parent_map.id(), SE3());
    if (bridge) {
      out.linked = bridgeOrigin(parent_map, origin);
      out.linked_again = bridgeOrigin(parent_map, origin);
    }
    auto childError = [&] {
      double worst_m = 0.0, worst_yaw_deg = 0.0;
      for (std::size_t k = 0; k < child.kfs.size(); ++k) {
        const SE3 T_true = world.T_w_b(child_times[k]);
        worst_m = std::max(worst_m, (child.kfs[k]->T_w_b().translation() - T_true.translation()).norm());
        worst_yaw_deg = std::max(worst_yaw_deg,
                                 std::abs(so3Log(T_true.quaternion() * child.kfs[k]->T_w_b().quaternion().conjugate()).z()) *
                                     kRadToDeg);
      }
      return std::make_pair(worst_m, worst_yaw_deg);
    };
    out.before_m = childError().first;
    GlobalBaOptions options;
    options.g_w = imu::gravityWorld();
    const GlobalBaSolution solution = optimizeGlobalBundleAdjustment(parent_map, options);
    EXPECT_TRUE(solution.valid);
    if (!solution.valid) return out;
    applyGlobalBundleAdjustment(parent_map, solution);
    out.inertial_links = solution.result.inertial_links;
    std::tie(out.after_m, out.yaw_after_deg) = childError();
    return out;
  };
  const Outcome with = run(true);
  const Outcome without = run(false);
  std::printf("[ BRIDGE   ] child map %.3f m off; full VI BA with the IMU across the loss: %.4f m, %.3f deg yaw (%d "
              "inertial links); without: %.4f m\n",
              with.before_m, with.after_m, with.yaw_after_deg, with.inertial_links, without.after_m);
  EXPECT_TRUE(with.linked);
  EXPECT_FALSE(with.linked_again);  // once only
  EXPECT_EQ(with.inertial_links, 11);  // 5 in the parent, 1 across, 5 in the child
  EXPECT_EQ(without.inertial_links, 10);
  EXPECT_GT(with.before_m, 0.1);
  EXPECT_LT(with.after_m, 0.01);
  EXPECT_LT(with.yaw_after_deg, 0.1);
  EXPECT_GT(without.after_m, 0.1);
}

/// Consecutive losses (parent -> `middles` maps -> child), no middle map matched by a place: the
/// child is merged into the parent (here at its true place), then absorbBridgedMiddle; `before_m` /
/// `after_m` are the worst middle keyframe's position error before / after the full VI BA.
struct MiddleChainOutcome {
  int absorbed = 0;
  int again = 0;  // absorbBridgedMiddle a second time
  std::size_t maps = 0;
  bool all_in_parent = false;
  bool chain_linked = false;  // every first keyframe's previous keyframe is the keyframe before the loss
  int inertial_links = 0;
  double before_m = 0.0;
  double after_m = 0.0;
};

MiddleChainOutcome absorbMiddleChain(int middles) {
  std::mt19937 rng(67);
  const std::vector<double> times = test::sceneTimes(5 * (middles + 1) + 5);
  test::SceneWorld world;
  world.addPointsSeenAt(times, 40, rng);
  // Four keyframes a map (five for the child), one keyframe time lost between maps.
  auto segment = [&](int index, int length) {
    return std::vector<double>(times.begin() + 5 * index, times.begin() + 5 * index + length);
  };
  map::Atlas atlas(100000);
  auto same = [](int, const SE3& T) { return T; };
  auto bias = [](int) { return test::sceneBias(); };
  map::Map& parent_map = atlas.activeMap();
  const std::vector<double> parent_times = segment(0, 4);
  const test::SceneMap parent =
      test::buildSceneMap(parent_map, world, parent_times, same, [](int, const Vec3& v) { return v; }, bias);
  auto originOf = [&](map::MapId parent_id, const std::shared_ptr<map::KeyFrame>& from, double t_from,
                      const std::shared_ptr<map::KeyFrame>& first, double t_first) {
    map::MapOrigin origin;
    origin.parent = parent_id;
    origin.parent_keyframe = from->id();
    origin.T_w_b_parent_keyframe = from->T_w_b();
    origin.first_keyframe = first->id();
    auto across = std::make_shared<imu::Preintegrated>(imu::ImuBias(), imu::ImuNoise());
    across->integrate(world.trajectory.samples(t_from, t_first, 200.0, test::sceneBias()));
    origin.imu_across = across;
    return origin;
  };
  // The middle maps: each placed by a short dead reckoning (3-8 cm, 0.3 deg of yaw off).
  std::vector<test::SceneMap> middle;
  std::vector<std::vector<double>> middle_times;
  std::vector<map::MapId> middle_ids;
  map::MapId before_id = parent_map.id();
  std::shared_ptr<map::KeyFrame> before_last = parent.kfs.back();
  double before_t = parent_times.back();
  for (int i = 0; i < middles; ++i) {
    map::Map& middle_map = atlas.createNewMap();
    const double sign = i % 2 == 0 ? 1.0 : -1.0;
    const SE3 T_middle(so3ExpQuat(Vec3(0.0, 0.0, sign * 0.3 / kRadToDeg)), Vec3(0.03, sign * 0.04, -0.01 * (i + 1)));
    middle_times.push_back(segment(i + 1, 4));
    middle.push_back(test::buildSceneMap(
        middle_map, world, middle_times.back(), [&](int, const SE3& T) { return T_middle * T; },
        [&](int, const Vec3& v) -> Vec3 { return T_middle.rotationMatrix() * v; }, bias));
    middle_map.setOrigin(
        originOf(before_id, before_last, before_t, middle.back().kfs.front(), middle_times.back().front()));
    middle_ids.push_back(middle_map.id());
    before_id = middle_map.id();
    before_last = middle.back().kfs.back();
    before_t = middle_times.back().back();
  }
  // The child: far off, then merged at its true place (what its place match gives).
  map::Map& child_map = atlas.createNewMap();
  const std::vector<double> child_times = segment(middles + 1, 5);
  const SE3 T_child(so3ExpQuat(Vec3(0.0, 0.0, 2.0 / kRadToDeg)), Vec3(0.2, -0.1, 0.02));
  const test::SceneMap child = test::buildSceneMap(
      child_map, world, child_times, [&](int, const SE3& T) { return T_child * T; },
      [&](int, const Vec3& v) -> Vec3 { return T_child.rotationMatrix() * v; }, bias);
  const map::MapOrigin child_origin =
      originOf(before_id, before_last, before_t, child.kfs.front(), child_times.front());
  child_map.setOrigin(child_origin);
  atlas.mergeMaps(child_map.id(), parent_map.id(), T_child.inverse());
  EXPECT_FALSE(bridgeOrigin(parent_map, child_origin));  // its parent keyframe is in a middle map
  EXPECT_EQ(atlas.numMaps(), static_cast<std::size_t>(middles + 1));

  MiddleChainOutcome out;
  out.absorbed = absorbBridgedMiddle(atlas, parent_map, child_origin, imu::gravityWorld());
  auto middleError_m = [&] {
    double worst = 0.0;
    for (std::size_t i = 0; i < middle.size(); ++i) {
      for (std::size_t k = 0; k < middle[i].kfs.size(); ++k) {
        const Vec3 truth = world.T_w_b(middle_times[i][k]).translation();
        worst = std::max(worst, (middle[i].kfs[k]->T_w_b().translation() - truth).norm());
      }
    }
    return worst;
  };
  out.before_m = middleError_m();
  GlobalBaOptions options;
  options.g_w = imu::gravityWorld();
  const GlobalBaSolution solution = optimizeGlobalBundleAdjustment(parent_map, options);
  EXPECT_TRUE(solution.valid);
  if (!solution.valid) return out;
  applyGlobalBundleAdjustment(parent_map, solution);
  out.after_m = middleError_m();
  out.inertial_links = solution.result.inertial_links;
  out.maps = atlas.numMaps();
  out.all_in_parent = true;
  for (const map::MapId id : middle_ids) out.all_in_parent = out.all_in_parent && atlas.resolve(id) == parent_map.id();
  out.chain_linked = child.kfs.front()->previousKeyFrame() == middle.back().kfs.back()->id();
  std::shared_ptr<map::KeyFrame> last_before = parent.kfs.back();
  for (const test::SceneMap& m : middle) {
    out.chain_linked = out.chain_linked && m.kfs.front()->previousKeyFrame() == last_before->id();
    last_before = m.kfs.back();
  }
  out.again = absorbBridgedMiddle(atlas, parent_map, child_origin, imu::gravityWorld());
  return out;
}

/// absorbMiddleChain(middles): every middle map merged into the parent, every loss linked (one more
/// inertial link than middle maps across the losses, besides 3 per four-keyframe map and 4 in the
/// child), and the full VI BA puts the middle maps from 4-5 cm off onto the truth.
void expectMiddleChainAbsorbed(int middles) {
  const MiddleChainOutcome out = absorbMiddleChain(middles);
  std::printf("[ MIDDLE   ] absorbed %d of %d: middle maps %.4f m off -> %.5f m after the full VI BA (%d inertial "
              "links)\n",
              out.absorbed, middles, out.before_m, out.after_m, out.inertial_links);
  EXPECT_EQ(out.absorbed, middles);
  EXPECT_EQ(out.maps, 1u);
  EXPECT_TRUE(out.all_in_parent);
  EXPECT_TRUE(out.chain_linked);
  EXPECT_EQ(out.inertial_links, 3 + 3 * middles + 4 + (middles + 1));
  EXPECT_GT(out.before_m, 0.04);
  EXPECT_LT(out.after_m, 0.005);
  EXPECT_EQ(out.again, 0);  // nothing more to absorb
}

// Two losses in a row (parent -> middle -> child), the middle map never matched by a place: once the
// child is merged into the parent, the middle map hangs on the IMU at both ends; absorbBridgedMiddle
// merges it at its dead-reckoned place (5 cm and 0.3 deg off) and bridges both losses (12 inertial
// links), and the full VI BA puts it at the truth.
TEST(MapMerger, AMapBetweenTwoLossesIsMergedOnTheImuAcrossBoth) { expectMiddleChainAbsorbed(1); }

// Three losses in a row (parent -> middle 1 -> middle 2 -> child), seen on ltlo_s3 when a box
// sweeps the view twice: both middle maps are merged, oldest first, every loss bridged (16 links).
TEST(MapMerger, TwoMapsBetweenThreeLossesAreMergedOldestFirst) { expectMiddleChainAbsorbed(2); }

}  // namespace
}  // namespace ltlo::loop
