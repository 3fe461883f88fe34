// The movers of issue 32's harder worlds: plain movers and panels, the occluded start, walking
// figures, swinging doors and three movers at once.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <set>

#include "ltlo/sim/simulator.h"

namespace ltlo::sim {
namespace {

constexpr double kDeg = M_PI / 180.0;

SimOptions smallOptions(Scenario scenario, double seconds, uint64_t seed) {
  SimOptions o;
  o.width_px = 160;
  o.height_px = 120;
  o.scenario = scenario;
  o.seed = seed;
  o.duration_s = seconds;
  o.noise_free = true;
  return o;
}

// The room (photographs decoded once per test process; each simulator reschedules its movers).
const Scene& sharedRoom() {
  static const Scene room = Scene::buildRoom(SimOptions().texture_dir);
  return room;
}

double percentile(std::vector<double> values, double q) {
  EXPECT_FALSE(values.empty());
  if (values.empty()) return 0.0;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(q * values.size()));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[k];
}

// Intensity std of every 5x5 window lying wholly on the visible pixels of mover `label`.
std::vector<double> windowStds(const SimFrame& frame, const cv::Mat& labels, int label) {
  cv::Mat gray, on;
  cv::cvtColor(frame.bgr, gray, cv::COLOR_BGR2GRAY);
  cv::bitwise_and(frame.mask, labels == label, on);
  std::vector<double> stds;
  for (int v = 2; v + 2 < gray.rows; ++v)
    for (int u = 2; u + 2 < gray.cols; ++u) {
      const cv::Rect window(u - 2, v - 2, 5, 5);
      if (cv::countNonZero(on(window)) < 25) continue;
      cv::Scalar mean, std;
      cv::meanStdDev(gray(window), mean, std);
      stds.push_back(std[0]);
    }
  return stds;
}

// Pixels of each label in a render of the movers alone.
std::map<int, int> labelCounts(const cv::Mat& labels) {
  std::map<int, int> counts;
  for (auto it = labels.begin<uint8_t>(); it != labels.end<uint8_t>(); ++it)
    if (*it) ++counts[*it];
  return counts;
}

int frameAt(const Simulator& sim, double t_s) { return static_cast<int>(std::lround(t_s * sim.options().fps)); }

// ---- plain movers --------------------------------------------------------------------------------

// --plain-movers keeps the schedule (times, distances, lateral places, sways; the boxes' sizes and
// the near bottom edge of every panel), makes every mover one colour and half of the events panels
// (as wide and tall as the boxes they replace; with --tall-panels larger, the rest the same).
TEST(PlainMovers, KeepTheScheduleAndMakeHalfOfTheEventsPanels) {
  SimOptions o = smallOptions(Scenario::kMtlo, 40.0, 3);
  o.width_px = 320;
  o.height_px = 240;
  o.occlusion_at_s = {31.0};
  Simulator textured(o, sharedRoom());
  o.plain_movers = true;
  Simulator plain(o, sharedRoom());
  o.tall_panels = true;
  Simulator tall(o, sharedRoom());
  const std::vector<DynamicBox>& a = textured.scene().boxes;
  const std::vector<DynamicBox>& b = plain.scene().boxes;
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(a.size(), tall.scene().boxes.size());
  std::set<int> events, panel_events;
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].t_in_s, b[i].t_in_s);
    EXPECT_EQ(a[i].t_out_s, b[i].t_out_s);
    EXPECT_EQ(a[i].distance_m, b[i].distance_m);
    EXPECT_EQ(a[i].lateral_m, b[i].lateral_m);
    EXPECT_EQ(a[i].side, b[i].side);
    EXPECT_EQ(a[i].sway_phase, b[i].sway_phase);
    EXPECT_EQ(a[i].event, b[i].event);
    EXPECT_TRUE(b[i].plain && !a[i].plain);
    events.insert(b[i].event);
    // The same panels and colours with --tall-panels, only larger.
    const DynamicBox& c = tall.scene().boxes[i];
    EXPECT_EQ(b[i].panel, c.panel);
    EXPECT_EQ(b[i].plain_rgb, c.plain_rgb);
    EXPECT_EQ(b[i].size_m.x(), c.size_m.x());
    if (b[i].panel) {
      panel_events.insert(b[i].event);
      // As wide and tall as the box it replaces, thin.
      EXPECT_GE(b[i].size_m.x(), 0.03);
      EXPECT_LE(b[i].size_m.x(), 0.05);
      EXPECT_EQ(b[i].size_m.y(), a[i].size_m.y());
      EXPECT_EQ(b[i].size_m.z(), a[i].size_m.z());
      EXPECT_GE(c.size_m.y(), 1.0);
      EXPECT_LE(c.size_m.y(), 1.4);
      EXPECT_GE(c.size_m.z(), 1.5);
      EXPECT_LE(c.size_m.z(), 2.0);
    } else {
      EXPECT_EQ(a[i].size_m, b[i].size_m);
      EXPECT_EQ(a[i].size_m, c.size_m);
    }
  }
  ASSERT_GE(events.size(), 3u);
  EXPECT_EQ(panel_events.size(), (events.size() + 1) / 2);
  for (const std::vector<render::Mesh>& parts : plain.scene().moverMeshes()) EXPECT_EQ(parts[0].texture, -1);

  for (double t = 0.0; t < o.duration_s; t += 0.2) {
    const auto pa = textured.scene().dynamicPoses(t, textured.trajectory());
    const auto pb = plain.scene().dynamicPoses(t, plain.trajectory());
    ASSERT_EQ(pa.size(), pb.size()) << t;
    for (size_t k = 0; k < pa.size(); ++k) {
      ASSERT_EQ(pa[k].first, pb[k].first);
      // In the floor frame the same rotation, the centres apart by the change of half the depth
      // and of half the height only (near faces and footprints where they were).
      const SE3 T_floor_w = textured.trajectory().T_w_floor(t).inverse();
      const SE3 T_a = T_floor_w * pa[k].second, T_b = T_floor_w * pb[k].second;
      const Vec3 half_change = 0.5 * (b[pb[k].first].size_m - a[pa[k].first].size_m);
      EXPECT_LT((T_b.translation() - T_a.translation() - Vec3(half_change.x(), 0.0, half_change.z())).norm(), 1e-9)
          << t;
      EXPECT_LT(so3Log(T_a.rotationMatrix().transpose() * T_b.rotationMatrix()).norm(), 1e-12);
    }
  }

  // A plain face is one grey level before noise: 5x5 windows wholly on a mover have (almost) no
  // intensity spread, where the photo texture's spread is large.
  int checked = 0;
  for (int i = 0; i < textured.numFrames() && checked < 3; i += 15) {
    const render::RenderResult movers = plain.renderDynamicOnly(i);
    const std::map<int, int> counts = labelCounts(movers.labels);
    if (counts.empty()) continue;
    const auto largest = std::max_element(counts.begin(), counts.end(),
                                          [](const auto& x, const auto& y) { return x.second < y.second; });
    if (largest->second < static_cast<int>(movers.labels.total() / 5)) continue;
    const std::vector<double> plain_stds = windowStds(plain.renderFrame(i), movers.labels, largest->first);
    const std::vector<double> textured_stds =
        windowStds(textured.renderFrame(i), textured.renderDynamicOnly(i).labels, largest->first);
    ASSERT_GT(plain_stds.size(), 1000u) << i;
    RecordProperty(
        "window_std_plain_p99_textured_p75_frame" + std::to_string(i),
        std::to_string(percentile(plain_stds, 0.99)) + " " + std::to_string(percentile(textured_stds, 0.75)));
    EXPECT_LT(percentile(plain_stds, 0.99), 1.0) << "frame " << i;
    EXPECT_GT(percentile(textured_stds, 0.75), 5.0) << "frame " << i;
    ++checked;
  }
  EXPECT_EQ(checked, 3);
}

// ---- occluded start ------------------------------------------------------------------------------

// At VGA the box covers 40-80 % of frame 0, has slid out of the view before it is taken away
// (the last frame it exists in shows none of it), and nothing is dynamic at 5.5 s.
TEST(OccludedStart, CoversFrameZeroAndHasLeftTheViewByFiveSeconds) {
  for (const StartMove move : {StartMove::kAway, StartMove::kTowards}) {
    for (uint64_t seed : {1, 2, 3}) {
      SimOptions o = smallOptions(Scenario::kStatic, 6.0, seed);
      o.width_px = 640;
      o.height_px = 480;
      o.occluded_start = move;
      Simulator sim(o, sharedRoom());
      ASSERT_EQ(sim.scene().boxes.size(), 1u);
      const DynamicBox& box = sim.scene().boxes[0];
      EXPECT_LE(box.t_out_s, 5.0);
      EXPECT_GE(box.t_move_s, 1.5);
      EXPECT_LE(box.t_move_s, 3.5);
      const double share0 = sim.renderFrame(0).dynamic_fraction;
      RecordProperty("share0_seed" + std::to_string(seed) + (move == StartMove::kAway ? "_away" : "_towards"),
                     std::to_string(share0));
      EXPECT_GE(share0, 0.4) << seed;
      EXPECT_LE(share0, 0.8) << seed;
      const int last = static_cast<int>(std::ceil(box.t_out_s * o.fps)) - 1;
      EXPECT_EQ(sim.renderFrame(last).dynamic_fraction, 0.0) << seed;
      EXPECT_EQ(sim.renderFrame(frameAt(sim, 5.5)).dynamic_fraction, 0.0) << seed;
      // Its near face: pushed away it only gets further, pulled towards it comes to 0.35 m.
      double nearest_m = 1e9, furthest_m = 0.0;
      for (double t = 0.0; t < box.t_out_s; t += 0.01) {
        const auto poses = sim.scene().dynamicPoses(t, sim.trajectory());
        ASSERT_EQ(poses.size(), 1u);
        const SE3 T_floor_o = sim.trajectory().T_w_floor(t).inverse() * poses[0].second;
        const double distance_m =
            T_floor_o.translation().x() - 0.5 * box.size_m.x() - SimOptions::T_b_c().translation().x();
        nearest_m = std::min(nearest_m, distance_m);
        furthest_m = std::max(furthest_m, distance_m);
      }
      if (move == StartMove::kAway) {
        EXPECT_NEAR(nearest_m, box.distance_m, 1e-9);
        EXPECT_NEAR(furthest_m, box.distance_m + 1.0, 1e-3);
      } else {
        EXPECT_NEAR(nearest_m, 0.35, 1e-3);
      }
    }
  }
}

// With a still start the box stands in the world until it moves; the scenario's events that would
// overlap the first 5 s are dropped, the later ones kept.
TEST(OccludedStart, StandsStillWithTheRobotAndClearsTheScenarioStart) {
  SimOptions o = smallOptions(Scenario::kLtlo, 30.0, 2);
  o.stills = {{0.0, 3.0}};
  Simulator plain_ltlo(o, sharedRoom());
  o.occluded_start = StartMove::kTowards;
  Simulator sim(o, sharedRoom());
  const DynamicBox* start = nullptr;
  for (const DynamicBox& b : sim.scene().boxes) {
    if (b.start_move != StartMove::kNone)
      start = &b;
    else
      EXPECT_GT(b.t_in_s, 5.0);
  }
  ASSERT_NE(start, nullptr);
  int kept = 0;
  for (const DynamicBox& b : plain_ltlo.scene().boxes) kept += b.t_in_s > 5.0;
  EXPECT_EQ(static_cast<int>(sim.scene().boxes.size()), kept + 1);
  const SE3 T_w_o0 = sim.scene().dynamicPoses(0.0, sim.trajectory())[0].second;
  for (double t = 0.0; t < std::min(3.0, start->t_move_s); t += 0.05) {
    const SE3 T_w_o = sim.scene().dynamicPoses(t, sim.trajectory())[0].second;
    EXPECT_EQ((T_w_o.translation() - T_w_o0.translation()).norm(), 0.0) << t;
  }
}

// ---- walkers -------------------------------------------------------------------------------------

double pitchOf(const SE3& T) {  // forward swing of a part hanging along -z
  const Vec3 down = T.rotationMatrix() * Vec3(0, 0, -1);
  return std::atan2(down.x(), -down.z());
}

double lowestFootZ(const std::vector<render::Mesh>& meshes, const std::vector<SE3>& T_x_p) {
  double lowest = 1e9;
  for (const int part : {kFootLeft, kFootRight})
    for (const Eigen::Vector3f& p : meshes[part].positions_o)
      lowest = std::min(lowest, (T_x_p[part] * p.cast<double>()).z());
  return lowest;
}

// Over a gait cycle the hips swing +-25 deg, the knees bend 0-60 deg, each arm swings opposite to
// the leg of its side; one foot's sole is always on the floor and the pelvis bobs a few cm.
TEST(WalkerGait, LimbsSwingRelativeToTheTorsoAndAFootStaysOnTheFloor) {
  Walker walker;
  walker.height_m = 1.75;
  const std::vector<render::Mesh> meshes = walkerMeshes(walker);
  double hip_min = 1e9, hip_max = -1e9, knee_min = 1e9, knee_max = -1e9, pelvis_min = 1e9, pelvis_max = -1e9;
  double limb_motion_rad = 0.0;
  const std::vector<SE3> T0 = walkerPartPoses(walker, 0.0);
  for (int k = 0; k < 96; ++k) {
    const double phase = 2.0 * M_PI * k / 96;
    const std::vector<SE3> T = walkerPartPoses(walker, phase);
    ASSERT_EQ(T.size(), static_cast<size_t>(kNumWalkerParts));
    const SE3 T_torso_inv = T[kTorso].inverse();
    const double hip = pitchOf(T_torso_inv * T[kThighLeft]);
    const double knee = hip - pitchOf(T_torso_inv * T[kShankLeft]);
    hip_min = std::min(hip_min, hip);
    hip_max = std::max(hip_max, hip);
    knee_min = std::min(knee_min, knee);
    knee_max = std::max(knee_max, knee);
    EXPECT_LE(pitchOf(T_torso_inv * T[kUpperArmLeft]) * hip, 1e-12) << phase;  // opposite swings
    EXPECT_LE(pitchOf(T_torso_inv * T[kUpperArmRight]) * pitchOf(T_torso_inv * T[kThighRight]), 1e-12);
    EXPECT_NEAR(lowestFootZ(meshes, T), 0.0, 1e-6) << phase;
    pelvis_min = std::min(pelvis_min, T[kTorso].translation().z());
    pelvis_max = std::max(pelvis_max, T[kTorso].translation().z());
    for (int part = kUpperArmLeft; part < kNumWalkerParts; ++part)  // non-rigid: limbs move on the torso
      limb_motion_rad =
          std::max(limb_motion_rad, so3Log((T0[kTorso].inverse() * T0[part]).rotationMatrix().transpose() *
                                           (T_torso_inv * T[part]).rotationMatrix())
                                        .norm());
  }
  EXPECT_NEAR(hip_max, 25.0 * kDeg, 0.1 * kDeg);
  EXPECT_NEAR(hip_min, -25.0 * kDeg, 0.1 * kDeg);
  EXPECT_NEAR(knee_min, 0.0, 1e-9);
  EXPECT_NEAR(knee_max, 60.0 * kDeg, 0.5 * kDeg);
  EXPECT_GT(limb_motion_rad, 40.0 * kDeg);
  RecordProperty("pelvis_bob_mm", std::to_string(1e3 * (pelvis_max - pelvis_min)));
  EXPECT_GT(pelvis_max - pelvis_min, 0.01);
  EXPECT_LT(pelvis_max - pelvis_min, 0.1);
  EXPECT_GT(pelvis_min, 0.8);  // legs about straight under a 1.75 m figure
}

// In the world: feet on the floor; a leading walker 1.0-2.5 m ahead of the camera walking with the
// robot, a crossing one passing the optical axis perpendicular to the robot's heading at 1.0-1.4 m/s.
TEST(Walkers, LeadAheadOrCrossTheViewWithTheirFeetOnTheFloor) {
  int leading = 0, crossing = 0;
  for (uint64_t seed : {1, 2, 3}) {
    SimOptions o = smallOptions(Scenario::kStatic, 45.0, seed);
    o.walkers = 6;
    Simulator sim(o, sharedRoom());
    const RobotTrajectory& trajectory = sim.trajectory();
    ASSERT_EQ(sim.scene().walkers.size(), 6u);
    for (const Walker& w : sim.scene().walkers) {
      const std::vector<render::Mesh> meshes = walkerMeshes(w);
      int present = 0;
      for (double t = w.t_in_s; t < w.t_out_s; t += 0.1) {
        const std::optional<WalkerState> state = walkerState(w, t, trajectory);
        if (!state) continue;
        ++present;
        std::vector<SE3> T_w_p = walkerPartPoses(w, state->phase_rad);
        for (SE3& T : T_w_p) T = state->T_w_f * T;
        EXPECT_NEAR(lowestFootZ(meshes, T_w_p), 0.0, 1e-6) << t;
        if (w.kind == Walker::Kind::kLeading && t > w.t_in_s + 2.0 && t < w.t_out_s - 2.0) {
          const Vec3 p_floor = trajectory.T_w_floor(t).inverse() * state->T_w_f.translation();
          const double ahead_m = p_floor.x() - SimOptions::T_b_c().translation().x();
          EXPECT_GE(ahead_m, 1.0) << t;
          EXPECT_LE(ahead_m, 2.5) << t;
          EXPECT_LT(std::abs(p_floor.y()), 0.31) << t;
          EXPECT_LT(state->speed_mps, 1.2) << t;
        }
      }
      EXPECT_GT(present, 20);
      if (w.kind == Walker::Kind::kLeading) {
        ++leading;
        continue;
      }
      ++crossing;
      const std::optional<WalkerState> mid = walkerState(w, w.t_mid_s, trajectory);
      ASSERT_TRUE(mid.has_value());
      const SE3 T_floor_f = trajectory.T_w_floor(w.t_mid_s).inverse() * mid->T_w_f;
      EXPECT_LT(std::abs(T_floor_f.rotationMatrix()(0, 0)), 1e-9);  // walks across the heading
      EXPECT_NEAR(std::abs(T_floor_f.translation().y() - SimOptions::T_b_c().translation().y()), 0.0, 1e-9);
      EXPECT_GE(T_floor_f.translation().x(), 1.2);
      EXPECT_LE(T_floor_f.translation().x(), 3.2);
      EXPECT_GE(mid->speed_mps, 1.0);
      EXPECT_LE(mid->speed_mps, 1.4);
    }
  }
  EXPECT_GE(leading, 3);
  EXPECT_GE(crossing, 3);
}

// A figure of 12 parts is one mover: one label in the render of the movers, the mask exactly its
// visible pixels and 0 elsewhere.
TEST(Walkers, OneLabelPerFigureAndTheMaskIsExactlyItsVisiblePixels) {
  SimOptions o = smallOptions(Scenario::kStatic, 20.0, 1);
  o.width_px = 320;
  o.height_px = 240;
  o.walkers = 2;
  Simulator sim(o, sharedRoom());
  int checked = 0;
  for (int i = 0; i < sim.numFrames(); i += 10) {
    const render::RenderResult movers = sim.renderDynamicOnly(i);
    const std::map<int, int> counts = labelCounts(movers.labels);
    for (const auto& [label, count] : counts) EXPECT_TRUE(label == 1 || label == 2) << label;
    if (counts.empty() || counts.begin()->second < static_cast<int>(movers.labels.total() / 50)) continue;
    const SimFrame frame = sim.renderFrame(i);
    const render::RenderResult room = sim.renderStaticOnly(i);
    int wrong = 0;
    for (int v = 0; v < frame.mask.rows; ++v)
      for (int u = 0; u < frame.mask.cols; ++u) {
        const float zd = movers.depth_m.at<float>(v, u), zs = room.depth_m.at<float>(v, u);
        wrong += (zd > 0 && (zs == 0 || zd < zs)) != (frame.mask.at<uint8_t>(v, u) == 255);
      }
    EXPECT_EQ(wrong, 0) << "frame " << i;
    ++checked;
  }
  EXPECT_GE(checked, 5);
}

// ---- doors ---------------------------------------------------------------------------------------

// Distance in the floor plane from p to a leaf (a segment from its hinge, thickened by half its thickness).
double distanceToLeaf(const Vec2& p, const Door& door, double angle_rad) {
  const double yaw = door.closed_yaw_rad + door.open_sign * angle_rad;
  const Vec2 hinge = door.hinge_w.head<2>(), tip = hinge + door.width_m * Vec2(std::cos(yaw), std::sin(yaw));
  const double s = std::clamp((p - hinge).dot(tip - hinge) / (tip - hinge).squaredNorm(), 0.0, 1.0);
  return (p - (hinge + s * (tip - hinge))).norm() - 0.5 * door.thickness_m;
}

// Each leaf swings between 0 and at most 100 deg, held at both ends, about a hinge edge fixed in the world.
TEST(Doors, LeavesSwingWithinTheirBoundsAboutAFixedHingeEdge) {
  SimOptions o = smallOptions(Scenario::kStatic, 60.0, 1);
  o.doors = true;
  Simulator sim(o, sharedRoom());
  ASSERT_EQ(sim.scene().doors.size(), 3u);
  EXPECT_EQ(sim.scene().door_frames.size(), 9u);
  for (const Door& door : sim.scene().doors) {
    EXPECT_LE(door.max_angle_rad, 100.0 * kDeg + 1e-12);
    double closed_s = 0.0, open_s = 0.0, largest = 0.0;
    for (double t = 0.0; t < o.duration_s; t += 0.01) {
      const double angle = doorAngle(door, t);
      ASSERT_GE(angle, 0.0);
      ASSERT_LE(angle, door.max_angle_rad);
      largest = std::max(largest, angle);
      closed_s += angle == 0.0 ? 0.01 : 0.0;
      open_s += angle == door.max_angle_rad ? 0.01 : 0.0;
      const SE3 T_w_leaf = doorLeafPose(door, t);
      for (const double z : {-0.5, 0.5}) {  // the hinge edge's ends
        const Vec3 p_w = T_w_leaf * Vec3(-0.5 * door.width_m, 0.0, z * door.height_m);
        EXPECT_LT((p_w.head<2>() - door.hinge_w.head<2>()).norm(), 1e-9) << t;
      }
    }
    EXPECT_EQ(largest, door.max_angle_rad);
    EXPECT_GT(closed_s, 5.0);
    EXPECT_GT(open_s, 5.0);
  }
}

// Where the leaves sweep is at least 0.3 m from the camera's path (seeds 1-5, two laps).
TEST(Doors, LeavesNeverComeWithinThirtyCentimetresOfTheCameraPath) {
  SimOptions o = smallOptions(Scenario::kStatic, 1.0, 1);
  o.doors = true;
  Simulator sim(o, sharedRoom());
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const RobotTrajectory trajectory(TrajectoryParams{}, seed);
    double closest_m = 1e9;
    for (double t = 0.0; t < 70.0; t += 0.05) {
      const Vec2 camera = (trajectory.state(t).T_w_b * SimOptions::T_b_c()).translation().head<2>();
      for (const Door& door : sim.scene().doors)
        for (double angle = 0.0; angle <= door.max_angle_rad; angle += 1.0 * kDeg)
          closest_m = std::min(closest_m, distanceToLeaf(camera, door, angle));
    }
    RecordProperty("closest_mm_seed" + std::to_string(seed), std::to_string(1e3 * closest_m));
    EXPECT_GT(closest_m, 0.3) << "seed " << seed;
  }
}

// A leaf is a mover all the time: at rest (closed) it is in the mask as well; the leaves are in
// view for a good share of the run.
TEST(Doors, ALeafIsInTheMaskAlsoWhenAtRest) {
  SimOptions o = smallOptions(Scenario::kStatic, 35.0, 1);
  o.width_px = 80;
  o.height_px = 60;
  o.fps = 5.0;
  o.doors = true;
  Simulator sim(o, sharedRoom());
  int in_view = 0, at_rest_in_mask = 0;
  for (int i = 0; i < sim.numFrames(); ++i) {
    const double t_s = sim.frameTime(i);
    const SimFrame frame = sim.renderFrame(i);
    const render::RenderResult movers = sim.renderDynamicOnly(i);
    if (frame.dynamic_fraction > 0.01) ++in_view;
    for (const auto& [label, count] : labelCounts(movers.labels)) {
      const Door& door = sim.scene().doors[label - 1];
      cv::Mat on;
      cv::bitwise_and(frame.mask, movers.labels == label, on);
      if (doorAngle(door, t_s) == 0.0 && cv::countNonZero(on) > 20) ++at_rest_in_mask;
    }
  }
  RecordProperty("share_in_view", std::to_string(in_view / static_cast<double>(sim.numFrames())));
  EXPECT_GT(at_rest_in_mask, 3);
  EXPECT_GT(in_view, sim.numFrames() / 4);
}

// ---- three movers --------------------------------------------------------------------------------

// From t_clear on: a lead box, crossing boxes and a carried box, three labels in view together in
// most frames; the carried box alone covers 20-30 % of the view.
TEST(ThreeMovers, ThreeLabelsAreInViewTogetherInMostFrames) {
  SimOptions o = smallOptions(Scenario::kLtlo, 40.0, 2);
  o.fps = 5.0;
  o.three_movers = true;
  Simulator sim(o, sharedRoom());
  const std::vector<DynamicBox>& boxes = sim.scene().boxes;
  ASSERT_GE(boxes.size(), 5u);
  int carried = -1;
  for (size_t k = 0; k < boxes.size(); ++k) {
    EXPECT_GE(boxes[k].t_in_s, 3.0);
    EXPECT_EQ(boxes[k].event, -1);  // the scenario's own events are gone
    if (boxes[k].carried) carried = static_cast<int>(k);
  }
  ASSERT_GE(carried, 0);
  int frames = 0, with_three = 0;
  std::vector<double> carried_share;
  for (int i = frameAt(sim, 5.0); i < sim.numFrames(); ++i) {
    const render::RenderResult movers = sim.renderDynamicOnly(i);
    int visible = 0;
    for (const auto& [label, count] : labelCounts(movers.labels)) {
      visible += count > static_cast<int>(movers.labels.total() / 200);
      if (label == carried + 1) carried_share.push_back(count / static_cast<double>(movers.labels.total()));
    }
    ++frames;
    with_three += visible >= 3;
  }
  RecordProperty("share_three_visible", std::to_string(with_three / static_cast<double>(frames)));
  EXPECT_GT(with_three, frames / 2);
  EXPECT_GT(percentile(carried_share, 0.5), 0.17);  // partly hidden by nothing: it is the nearest
  EXPECT_LT(percentile(carried_share, 0.5), 0.33);
}

}  // namespace
}  // namespace ltlo::sim
