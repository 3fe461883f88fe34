// Swinging doors (simulate --door): leaves on frame posts at fixed places of the room.
#include <cmath>

#include "ltlo/sim/movers.h"
#include "ltlo/sim/scene.h"
#include "mover_schedule.h"
#include "scene_layout.h"

namespace ltlo::sim {
namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kPostWidthM = 0.06, kPostDepthM = 0.08, kPostGapM = 0.03;
constexpr double kFloorGapM = 0.01;

// The doors' local frame: origin at the foot of the hinge axis, x along the closed leaf, z up, the
// wall behind at y = +kPostDepthM / 2; the leaf opens towards -y (into the room). Hinge axes 4 cm in
// front of the walls between the furniture of scene.cc; where the leaves sweep is at least 0.4 m from
// every seed's camera path (|x| < 2.7, and |y| < 1.7 where x is within these doorways).
struct DoorPlace {
  Vec2 hinge_w;
  double closed_yaw_rad;
};
const DoorPlace kDoorPlaces[] = {
    {{1.25, kRoomY - 0.04}, 0.0},          // +y wall, leaf towards +x: faced at the +x end of the loop
    {{-1.35, -kRoomY + 0.04}, M_PI},       // -y wall, leaf towards -x: faced at the -x end
    {{kRoomX - 0.04, 0.95}, -0.5 * M_PI},  // +x wall, leaf towards -y: ahead along the -y side
};

SE3 doorFrame(const Door& door, double opening_rad) {
  return SE3(Quat(Eigen::AngleAxisd(door.closed_yaw_rad + door.open_sign * opening_rad, Vec3::UnitZ())), door.hinge_w);
}

render::Mesh frameBox(const SE3& T_w_door, const Vec3& centre_door, const Vec3& size_m) {
  render::Mesh mesh = render::makeBoxMesh(size_m, -1);
  bakeFlatShading(&mesh);
  makePlain(&mesh, Vec3(0.9, 0.89, 0.85));
  const SE3 T_w_o = T_w_door * SE3(Quat::Identity(), centre_door);
  for (Eigen::Vector3f& p : mesh.positions_o) p = (T_w_o * p.cast<double>()).cast<float>();
  return mesh;
}

}  // namespace

double doorAngle(const Door& door, double t_s) {
  const double period_s = 2.0 * door.swing_s + door.open_hold_s + door.closed_hold_s;
  double u = std::fmod(t_s - door.t0_s, period_s);
  if (u < 0.0) u += period_s;
  if (u < door.closed_hold_s) return 0.0;
  u -= door.closed_hold_s;
  if (u < door.swing_s) return door.max_angle_rad * smoothstep(u / door.swing_s);
  u -= door.swing_s;
  if (u < door.open_hold_s) return door.max_angle_rad;
  u -= door.open_hold_s;
  return door.max_angle_rad * (1.0 - smoothstep(u / door.swing_s));
}

SE3 doorLeafPose(const Door& door, double t_s) {
  return doorFrame(door, doorAngle(door, t_s)) *
         SE3(Quat::Identity(), Vec3(0.5 * door.width_m, 0.0, kFloorGapM + 0.5 * door.height_m));
}

render::Mesh doorLeafMesh(const Door& door) {
  render::Mesh mesh =
      render::makeBoxMesh(Vec3(door.width_m, door.thickness_m, door.height_m), door.plain ? -1 : door.texture);
  bakeFlatShading(&mesh);
  if (door.plain) makePlain(&mesh, door.plain_rgb);
  return mesh;
}

std::vector<render::Mesh> doorFrameMeshes(const Door& door) {
  const SE3 T_w_door = doorFrame(door, 0.0);
  const double top = kFloorGapM + door.height_m + 0.01, lintel = 0.08;
  const double post_x = kPostGapM + 0.5 * kPostWidthM;
  return {frameBox(T_w_door, Vec3(-post_x, 0, 0.5 * (top + lintel)), Vec3(kPostWidthM, kPostDepthM, top + lintel)),
          frameBox(T_w_door, Vec3(door.width_m + post_x - 0.02, 0, 0.5 * (top + lintel)),
                   Vec3(kPostWidthM, kPostDepthM, top + lintel)),
          frameBox(T_w_door, Vec3(0.5 * door.width_m - 0.01, 0, top + 0.5 * lintel),
                   Vec3(door.width_m + 2.0 * (kPostGapM + kPostWidthM) - 0.02, kPostDepthM, lintel))};
}

void scheduleDoors(const SimOptions& options, Scene* scene) {
  if (!options.doors) return;
  Draw draw(options.seed * 0x6A09E667F3BCC909ULL + 0xBB67AE8584CAA73BULL);
  for (const DoorPlace& place : kDoorPlaces) {
    Door door;
    door.hinge_w = Vec3(place.hinge_w.x(), place.hinge_w.y(), 0.0);
    door.closed_yaw_rad = place.closed_yaw_rad;
    door.open_sign = -1.0;
    door.max_angle_rad = draw(90.0, 100.0) * kDeg;
    door.swing_s = draw(1.0, 1.6);
    door.open_hold_s = draw(0.8, 2.0);
    door.closed_hold_s = draw(1.0, 2.5);
    door.t0_s = -draw(0.0, 2.0 * door.swing_s + door.open_hold_s + door.closed_hold_s);
    door.texture = draw.dynamicTexture();
    scene->doors.push_back(door);
    for (render::Mesh& mesh : doorFrameMeshes(door)) scene->door_frames.push_back(std::move(mesh));
  }
}

}  // namespace ltlo::sim
