#pragma once
/// Movers beyond the pushed boxes (issue 32, "harder worlds"): articulated walking figures
/// (simulate --walkers N) and door leaves swinging at fixed places of the room (--door). Each is one
/// mover, so one label in the mask, however many rigid parts it has.
#include <optional>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/render/offscreen_renderer.h"
#include "ltlo/sim/robot_trajectory.h"

namespace ltlo::sim {

/// A walking person of rigid parts (WalkerPart) with a gait (walkerPartPoses), either leading the
/// robot (ahead of it in the floor frame, walking in its direction at about its speed) or crossing
/// its view on a straight line of the world.
struct Walker {
  enum class Kind { kLeading, kCrossing };
  Kind kind = Kind::kLeading;
  double t_in_s = 0.0;      ///< leading: starts walking in from the side; crossing: earliest start
  double t_out_s = 0.0;     ///< leading: has walked out; crossing: latest end (the walk is within)
  double height_m = 1.75;   ///< body height; every segment scales with it
  double phase0_rad = 0.0;  ///< gait phase at t_in_s

  // Leading (floor frame of the robot, x ahead, y left; distances from the camera)
  double distance_m = 1.8;        ///< mean distance ahead of the camera (1.0-2.5 m with the swing)
  double distance_swing_m = 0.3;  ///< amplitude of the slow change of distance
  double swing_period_s = 15.0;   ///< its period in path time (the robot's progress)
  double lateral_m = 0.0;         ///< lateral offset while ahead
  double side_in = 1.0;           ///< walks in from the left (+1) or right (-1)
  double side_out = 1.0;          ///< walks out to the left (+1) or right (-1)

  // Crossing (world line fixed from the robot's pose at t_mid_s)
  double t_mid_s = 0.0;              ///< passes the camera's optical axis at this time
  double speed_mps = 1.2;            ///< walking speed
  double crossing_distance_m = 2.0;  ///< distance of the crossing point ahead of the camera
  double from_side = 1.0;            ///< comes from the left (+1) or right (-1) of the robot

  // Appearance
  int shirt_texture = -1;    ///< torso and arms
  int trouser_texture = -1;  ///< legs (darkened by trouser_tint)
  Vec3 trouser_tint = Vec3(0.45, 0.45, 0.55);
  Vec3 skin_rgb = Vec3(0.85, 0.68, 0.55);
  bool plain = false;  ///< --plain-movers: shirt and trousers plain colours, no texture
  Vec3 shirt_rgb = Vec3::Ones(), trouser_rgb = Vec3::Ones();
};

/// The parts of a walking figure, in the order of walkerMeshes and walkerPartPoses.
enum WalkerPart {
  kTorso,
  kHead,
  kUpperArmLeft,
  kLowerArmLeft,
  kUpperArmRight,
  kLowerArmRight,
  kThighLeft,
  kShankLeft,
  kFootLeft,
  kThighRight,
  kShankRight,
  kFootRight,
  kNumWalkerParts
};

/// Gait amplitudes (degrees): hips +-25 (left leg 25 sin(phase)), knees 0-60 (flexed around early
/// swing), shoulders +-20 opposite to the leg of their side, elbows 12-30.
constexpr double kHipSwingDeg = 25.0, kKneeMaxDeg = 60.0, kShoulderSwingDeg = 20.0;

/// Poses T_f_p of the parts in the figure frame f (x the walking direction, y left, z up, origin on
/// the floor under the pelvis) at gait phase phase_rad. Each part's origin is its proximal joint
/// (pelvis, neck, shoulder, elbow, hip, knee, ankle); the pelvis height is set so the lowest point
/// of the feet is on z = 0 (which gives the vertical bob).
std::vector<SE3> walkerPartPoses(const Walker& walker, double phase_rad);
/// Meshes of the parts in their own frames (baked shading; clothing textured or plain, skin and
/// shoes plain).
std::vector<render::Mesh> walkerMeshes(const Walker& walker);
/// Gait cycle length (m) of a figure: two steps of the legs' swing.
double walkerStrideM(const Walker& walker);

struct WalkerState {
  SE3 T_w_f;               ///< figure frame in the world (on the floor, yaw only)
  double phase_rad = 0.0;  ///< gait phase (2 pi per stride walked)
  double speed_mps = 0.0;  ///< walking speed in the world
};
/// Where the figure is at t_s, or nothing when it is not present.
std::optional<WalkerState> walkerState(const Walker& walker, double t_s, const RobotTrajectory& trajectory);

/// A door leaf on a frame post at a fixed place in the world, swinging open and closed periodically:
/// closed (held), swings open over swing_s, held open, swings closed, held closed again...
struct Door {
  Vec3 hinge_w = Vec3::Zero();  ///< foot of the hinge axis on the floor (world)
  double closed_yaw_rad = 0.0;  ///< world yaw of the leaf (hinge towards its free edge) when closed
  double open_sign = -1.0;      ///< the yaw grows (+1) or shrinks (-1) as it opens
  double width_m = 0.85, height_m = 2.0, thickness_m = 0.04;
  double max_angle_rad = 100.0 * M_PI / 180.0;  ///< fully open
  double swing_s = 1.2;                         ///< duration of one swing (open or close)
  double open_hold_s = 1.0;                     ///< held fully open
  double closed_hold_s = 1.5;                   ///< held closed
  double t0_s = 0.0;                            ///< a cycle (starting closed, held) begins at t0_s
  int texture = -1;
  bool plain = false;
  Vec3 plain_rgb = Vec3::Ones();
};

/// Opening angle (rad, 0 = closed) at t_s; smoothstep swings.
double doorAngle(const Door& door, double t_s);
/// Pose of the leaf's centre (the frame of doorLeafMesh: x along the leaf, y through it, z up).
SE3 doorLeafPose(const Door& door, double t_s);
render::Mesh doorLeafMesh(const Door& door);
/// The static frame: two posts beside the doorway and a lintel over it (world frame, plain white).
std::vector<render::Mesh> doorFrameMeshes(const Door& door);

}  // namespace ltlo::sim
