// Walking figures (simulate --walkers N): body, gait, placement over time, schedule.
#include <cmath>
#include <string>

#include "ltlo/core/errors.h"
#include "ltlo/sim/movers.h"
#include "ltlo/sim/scene.h"
#include "mover_schedule.h"
#include "scene_layout.h"

namespace ltlo::sim {
namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kWalkInS = 2.0;      // a leading walker walks in (and out) over 2 s
constexpr double kWalkSlideM = 2.4;   // from (to) 2.4 m to the side
constexpr double kCrossReachM = 3.5;  // a crossing walk starts (ends) at most 3.5 m from the axis
constexpr double kMinSlotS = 5.0;     // run time per walker
constexpr double kSpeedStepS = 0.05;  // integration step of a leading walker's distance walked

// Segment lengths and radii (m) of a figure of height h (rounded anthropometric shares).
struct Body {
  explicit Body(double h)
      : thigh(0.245 * h),
        shank(0.245 * h),
        foot_height(0.04 * h),
        foot_length(0.15 * h),
        heel(0.035 * h),
        foot_width(0.055 * h),
        hip_y(0.055 * h),
        torso_bottom(-0.04 * h),
        torso_top(0.30 * h),
        torso_width(0.2 * h),
        torso_depth(0.11 * h),
        shoulder_z(0.27 * h),
        upper_arm(0.17 * h),
        lower_arm(0.23 * h),
        r_thigh(0.042 * h),
        r_shank(0.032 * h),
        r_upper_arm(0.026 * h),
        r_lower_arm(0.022 * h),
        neck(0.04 * h),
        r_neck(0.022 * h),
        head(0.11 * h, 0.09 * h, 0.125 * h),
        shoulder_y(0.5 * torso_width + r_upper_arm + 0.005) {}
  double thigh, shank, foot_height, foot_length, heel, foot_width, hip_y;
  double torso_bottom, torso_top, torso_width, torso_depth, shoulder_z;
  double upper_arm, lower_arm, r_thigh, r_shank, r_upper_arm, r_lower_arm, neck, r_neck;
  Vec3 head;
  double shoulder_y;
};

SE3 translation(const Vec3& t) { return SE3(Quat::Identity(), t); }
// Rotation about y that swings a part hanging along -z forwards (+x) by angle_rad.
SE3 swingForward(double angle_rad) { return SE3(Quat(Eigen::AngleAxisd(-angle_rad, Vec3::UnitY())), Vec3::Zero()); }

render::Mesh shifted(render::Mesh mesh, const Vec3& offset) {
  for (Eigen::Vector3f& p : mesh.positions_o) p += offset.cast<float>();
  return mesh;
}

// A limb: cylinder hanging from its joint (origin) along -z.
render::Mesh limb(double radius_m, double length_m, int texture) {
  return shifted(render::makeCylinderMesh(radius_m, length_m, 10, texture), Vec3(0, 0, -0.5 * length_m));
}

// Knee flexion profile in [0, 1] at leg phase x (hip angle 25 sin x): flexes from late stance,
// peaks in early swing (x = -pi/4), straight again by mid swing.
double kneeProfile(double x) {
  const double c = std::max(0.0, std::cos(x + 0.25 * M_PI));
  return c * c;
}

// Distance along unit dir from p to the boundary of |x| <= kRoomX - margin, |y| <= kRoomY - margin
// (0 when p is outside it).
double rayToRoomEdge(const Vec2& p, const Vec2& dir, double margin_m) {
  const Vec2 half(kRoomX - margin_m, kRoomY - margin_m);
  if (std::abs(p.x()) > half.x() || std::abs(p.y()) > half.y()) return 0.0;
  double reach = 1e9;
  for (int k = 0; k < 2; ++k)
    if (std::abs(dir[k]) > 1e-9) reach = std::min(reach, ((dir[k] > 0 ? half[k] : -half[k]) - p[k]) / dir[k]);
  return reach;
}

double yawOf(const SE3& T) { return std::atan2(T.rotationMatrix()(1, 0), T.rotationMatrix()(0, 0)); }

double wrapAngle(double a) { return std::atan2(std::sin(a), std::cos(a)); }

// Leading walker: position of the figure in the world at t_s (floor frame of the robot: ahead of
// the camera at its distance, walking in from and out to the side).
Vec3 leadingPosition(const Walker& w, double t_s, const RobotTrajectory& trajectory) {
  const double tau_s = trajectory.pathTimeAt(t_s) - trajectory.pathTimeAt(w.t_in_s);
  const double d = w.distance_m + w.distance_swing_m * std::sin(2.0 * M_PI * tau_s / w.swing_period_s + w.phase0_rad);
  const double y = w.lateral_m + w.side_in * kWalkSlideM * (1.0 - smoothstep((t_s - w.t_in_s) / kWalkInS)) +
                   w.side_out * kWalkSlideM * smoothstep((t_s - (w.t_out_s - kWalkInS)) / kWalkInS);
  const double x = SimOptions::T_b_c().translation().x() + d;
  return trajectory.T_w_floor(t_s) * Vec3(x, y, 0.0);
}

Vec3 leadingVelocity(const Walker& w, double t_s, const RobotTrajectory& trajectory) {
  constexpr double h = 1e-4;
  return (leadingPosition(w, t_s + h, trajectory) - leadingPosition(w, t_s - h, trajectory)) / (2.0 * h);
}

std::optional<WalkerState> leadingState(const Walker& w, double t_s, const RobotTrajectory& trajectory) {
  WalkerState state;
  const Vec3 p_w = leadingPosition(w, t_s, trajectory);
  const Vec3 v_w = leadingVelocity(w, t_s, trajectory);
  state.speed_mps = v_w.head<2>().norm();
  // Facing where it walks; at a standstill (the robot stopped) facing the robot's heading.
  const SE3 T_w_floor = trajectory.T_w_floor(t_s);
  const Vec3 v_floor = T_w_floor.rotationMatrix().transpose() * v_w;
  const double turn = smoothstep(state.speed_mps / 0.25) * std::atan2(v_floor.y(), v_floor.x());
  state.T_w_f = SE3(Quat(Eigen::AngleAxisd(yawOf(T_w_floor) + wrapAngle(turn), Vec3::UnitZ())), p_w);
  // Distance walked since t_in (Simpson's rule, steps of at most kSpeedStepS).
  const double span_s = t_s - w.t_in_s;
  const int n = 2 * std::max(1, static_cast<int>(std::ceil(span_s / (2.0 * kSpeedStepS))));
  double walked_m = 0.0;
  for (int k = 0; k <= n; ++k) {
    const double weight = (k == 0 || k == n) ? 1.0 : (k % 2 == 1 ? 4.0 : 2.0);
    walked_m += weight * leadingVelocity(w, w.t_in_s + span_s * k / n, trajectory).head<2>().norm();
  }
  walked_m *= span_s / (3.0 * n);
  state.phase_rad = w.phase0_rad + 2.0 * M_PI * walked_m / walkerStrideM(w);
  return state;
}

std::optional<WalkerState> crossingState(const Walker& w, double t_s, const RobotTrajectory& trajectory) {
  // The crossing line is fixed in the world by the robot's pose when the walker passes its view's axis.
  const SE3 T_w_floor = trajectory.T_w_floor(w.t_mid_s);
  const Vec2 heading = T_w_floor.rotationMatrix().col(0).head<2>().normalized();
  const Vec2 left(-heading.y(), heading.x());
  const Vec3 t_b_c = SimOptions::T_b_c().translation();
  const Vec2 camera = (T_w_floor * Vec3(t_b_c.x(), t_b_c.y(), 0.0)).head<2>();
  const Vec2 dir = -w.from_side * left;  // walking direction
  // Inside the room (0.5 m from the walls) where possible; the walk starts and ends behind the walls
  // or kCrossReachM from the axis, out of view (atan(reach / D) > 36 deg) when the room allows.
  double distance_m = std::max(1.2, std::min(w.crossing_distance_m, rayToRoomEdge(camera, heading, 0.5)));
  double reach_in = 0.0, reach_out = 0.0;
  Vec2 crossing;
  for (int pass = 0; pass < 2; ++pass) {
    crossing = camera + distance_m * heading;
    reach_in = std::min(kCrossReachM, rayToRoomEdge(crossing, -dir, -0.35));
    reach_out = std::min(kCrossReachM, rayToRoomEdge(crossing, dir, -0.35));
    const double fits_m = (std::min(reach_in, reach_out) - 0.3) / std::tan(36.0 * kDeg);
    if (fits_m >= distance_m) break;
    distance_m = std::max(1.2, fits_m);
  }
  const double t_start = w.t_mid_s - reach_in / w.speed_mps, t_end = w.t_mid_s + reach_out / w.speed_mps;
  if (t_s < t_start || t_s >= t_end) return std::nullopt;
  WalkerState state;
  const Vec2 p = crossing + dir * (w.speed_mps * (t_s - w.t_mid_s));
  state.T_w_f = SE3(Quat(Eigen::AngleAxisd(std::atan2(dir.y(), dir.x()), Vec3::UnitZ())), Vec3(p.x(), p.y(), 0.0));
  state.speed_mps = w.speed_mps;
  state.phase_rad = w.phase0_rad + 2.0 * M_PI * w.speed_mps * (t_s - t_start) / walkerStrideM(w);
  return state;
}

}  // namespace

double walkerStrideM(const Walker& walker) {
  const Body body(walker.height_m);
  return 4.0 * (body.thigh + body.shank) * std::sin(kHipSwingDeg * kDeg);  // two steps
}

std::vector<SE3> walkerPartPoses(const Walker& walker, double phase_rad) {
  const Body b(walker.height_m);
  std::vector<SE3> T_f_p(kNumWalkerParts);
  T_f_p[kTorso] = SE3();
  T_f_p[kHead] = translation(Vec3(0, 0, b.torso_top));
  for (const int side : {1, -1}) {  // left, then right; the right half a cycle later
    const double x = side == 1 ? phase_rad : phase_rad + M_PI;
    const double hip = kHipSwingDeg * kDeg * std::sin(x);
    const double knee = kKneeMaxDeg * kDeg * kneeProfile(x);
    const double shoulder = -kShoulderSwingDeg * kDeg * std::sin(x);  // opposite to the leg
    const double elbow = (12.0 + 18.0 * std::max(0.0, -std::sin(x))) * kDeg;
    const SE3 thigh = translation(Vec3(0, side * b.hip_y, 0)) * swingForward(hip);
    const SE3 shank = thigh * translation(Vec3(0, 0, -b.thigh)) * swingForward(-knee);
    // The foot pitches with half the shank's: toes down behind (push-off), heel down ahead.
    const SE3 foot = translation(shank * Vec3(0, 0, -b.shank)) * swingForward(0.5 * (hip - knee));
    const SE3 upper = translation(Vec3(0, side * b.shoulder_y, b.shoulder_z)) * swingForward(shoulder);
    const SE3 lower = upper * translation(Vec3(0, 0, -b.upper_arm)) * swingForward(elbow);
    T_f_p[side == 1 ? kThighLeft : kThighRight] = thigh;
    T_f_p[side == 1 ? kShankLeft : kShankRight] = shank;
    T_f_p[side == 1 ? kFootLeft : kFootRight] = foot;
    T_f_p[side == 1 ? kUpperArmLeft : kUpperArmRight] = upper;
    T_f_p[side == 1 ? kLowerArmLeft : kLowerArmRight] = lower;
  }
  // The pelvis is as high as puts the lowest corner of the soles on the floor.
  double lowest_m = 1e9;
  for (const int foot : {kFootLeft, kFootRight})
    for (const double x : {-b.heel, b.foot_length - b.heel})
      lowest_m = std::min(lowest_m, (T_f_p[foot] * Vec3(x, 0.0, -b.foot_height)).z());
  const SE3 lift = translation(Vec3(0, 0, -lowest_m));
  for (SE3& T : T_f_p) T = lift * T;
  return T_f_p;
}

std::vector<render::Mesh> walkerMeshes(const Walker& walker) {
  const Body b(walker.height_m);
  const int shirt = walker.plain ? -1 : walker.shirt_texture;
  const int trousers = walker.plain ? -1 : walker.trouser_texture;
  std::vector<render::Mesh> meshes(kNumWalkerParts);
  meshes[kTorso] = shifted(render::makeBoxMesh(Vec3(b.torso_depth, b.torso_width, b.torso_top - b.torso_bottom), shirt),
                           Vec3(0, 0, 0.5 * (b.torso_top + b.torso_bottom)));
  meshes[kHead] = limb(b.r_neck, b.neck, -1);
  meshes[kHead].append(shifted(render::makeBoxMesh(b.head, -1), Vec3(0.01, 0, b.neck + 0.5 * b.head.z())));
  for (const int side : {1, -1}) {
    meshes[side == 1 ? kUpperArmLeft : kUpperArmRight] = limb(b.r_upper_arm, b.upper_arm, shirt);
    meshes[side == 1 ? kLowerArmLeft : kLowerArmRight] = limb(b.r_lower_arm, b.lower_arm, shirt);
    meshes[side == 1 ? kThighLeft : kThighRight] = limb(b.r_thigh, b.thigh, trousers);
    meshes[side == 1 ? kShankLeft : kShankRight] = limb(b.r_shank, b.shank, trousers);
    meshes[side == 1 ? kFootLeft : kFootRight] =
        shifted(render::makeBoxMesh(Vec3(b.foot_length, b.foot_width, b.foot_height), -1),
                Vec3(0.5 * b.foot_length - b.heel, 0, -0.5 * b.foot_height));
  }
  for (int part = 0; part < kNumWalkerParts; ++part) {
    render::Mesh& mesh = meshes[part];
    bakeFlatShading(&mesh);
    const bool legs = part >= kThighLeft && part != kFootLeft && part != kFootRight;
    if (part == kHead) {
      makePlain(&mesh, walker.skin_rgb);
    } else if (part == kFootLeft || part == kFootRight) {
      makePlain(&mesh, Vec3(0.22, 0.2, 0.19));
    } else if (walker.plain) {
      makePlain(&mesh, legs ? walker.trouser_rgb : walker.shirt_rgb);
    } else if (legs) {
      for (Eigen::Vector3f& colour : mesh.colours_rgb) colour = colour.cwiseProduct(walker.trouser_tint.cast<float>());
    }
  }
  return meshes;
}

std::optional<WalkerState> walkerState(const Walker& walker, double t_s, const RobotTrajectory& trajectory) {
  if (t_s < walker.t_in_s || t_s >= walker.t_out_s) return std::nullopt;
  return walker.kind == Walker::Kind::kLeading ? leadingState(walker, t_s, trajectory)
                                               : crossingState(walker, t_s, trajectory);
}

void scheduleWalkers(const SimOptions& options, Scene* scene) {
  if (options.walkers <= 0) return;
  Draw draw(options.seed * 0xA0761D6478BD642FULL + 0xE7037ED1A0B428DBULL);
  const double t_start = std::max(clearTimeS(options), occludedStartEndS(*scene));
  const double slot_s = (options.duration_s - 1.0 - t_start) / options.walkers;
  if (slot_s < kMinSlotS)
    throw InputError("--walkers " + std::to_string(options.walkers) + ": each walker needs " +
                     std::to_string(static_cast<int>(kMinSlotS)) + " s of the run after its first " +
                     std::to_string(t_start) + " s; --seconds " + std::to_string(options.duration_s) +
                     " holds at most " +
                     std::to_string(std::max(0, static_cast<int>((options.duration_s - 1.0 - t_start) / kMinSlotS))));
  static const Vec3 kSkins[] = {{0.92, 0.76, 0.65}, {0.80, 0.62, 0.50}, {0.62, 0.45, 0.34}, {0.42, 0.30, 0.22}};
  for (int k = 0; k < options.walkers; ++k) {
    Walker w;
    w.height_m = draw(1.6, 1.9);
    w.phase0_rad = draw(0.0, 2.0 * M_PI);
    w.shirt_texture = draw.dynamicTexture();
    w.trouser_texture = draw.dynamicTexture();
    w.trouser_tint = Vec3::Constant(draw(0.35, 0.6)).cwiseProduct(Vec3(draw(0.8, 1.0), draw(0.8, 1.0), 1.0));
    w.skin_rgb = kSkins[draw.index(4)];
    const double slot_start = t_start + k * slot_s;
    if (draw.unit() < 0.5) {
      w.kind = Walker::Kind::kLeading;
      const double duration_s = std::min(draw(6.0, 12.0), slot_s - 0.5);
      w.t_in_s = slot_start + draw(0.0, slot_s - 0.5 - duration_s);
      w.t_out_s = w.t_in_s + duration_s;
      w.distance_m = draw(1.4, 2.1);
      w.distance_swing_m = std::min({0.35, w.distance_m - 1.0, 2.5 - w.distance_m});
      w.swing_period_s = draw(12.0, 20.0);
      w.lateral_m = draw(-0.3, 0.3);
      w.side_in = draw.sign();
      w.side_out = draw.sign();
    } else {
      w.kind = Walker::Kind::kCrossing;
      w.t_mid_s = slot_start + 0.5 * slot_s + draw(-0.25, 0.25) * slot_s;
      w.speed_mps = draw(1.0, 1.4);
      w.crossing_distance_m = draw(1.2, 3.0);
      w.from_side = draw.sign();
      w.t_in_s = w.t_mid_s - kCrossReachM / w.speed_mps;
      w.t_out_s = w.t_mid_s + kCrossReachM / w.speed_mps;
    }
    dropBoxesOverlapping(scene, w.t_in_s, w.t_out_s, false);
    scene->walkers.push_back(w);
  }
}

}  // namespace ltlo::sim
