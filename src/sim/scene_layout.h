#pragma once
// Layout constants and helpers shared by the room and the movers (private to ltlo_sim).
#include <algorithm>
#include <cstdint>
#include <random>

#include "ltlo/core/camera.h"
#include "ltlo/core/lie.h"
#include "ltlo/render/offscreen_renderer.h"

namespace ltlo::sim {

constexpr double kRoomX = 4.0, kRoomY = 3.0, kRoomZ = 3.0;  // half extents in x and y, height
constexpr double kEnterS = 1.0;                             // time a box takes to slide in (and out)
constexpr double kSlideM = 2.5;                             // lateral distance it slides over

// Texture index ranges (Scene::textures).
constexpr int kWallPanels = 14, kFloorTextures = 6, kFurnitureTextures = 8, kDynamicTextures = 6;
constexpr int kFirstFloor = kWallPanels, kCeiling = kFirstFloor + kFloorTextures;
constexpr int kFirstFurniture = kCeiling + 1, kFirstDynamic = kFirstFurniture + kFurnitureTextures;

inline double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

/// Uniform draws in [lo, hi) from one stream.
class Draw {
 public:
  explicit Draw(uint64_t seed) : rng_(seed) {}
  double operator()(double lo, double hi) { return lo + (hi - lo) * unit_(rng_); }
  double unit() { return unit_(rng_); }
  double sign() { return unit() < 0.5 ? -1.0 : 1.0; }
  int index(int count) { return std::min(count - 1, static_cast<int>(unit() * count)); }
  int dynamicTexture() { return kFirstDynamic + index(kDynamicTextures); }

 private:
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> unit_{0.0, 1.0};
};

/// One colour (RGB, 0..1) of the plain movers' palette: greys, off-whites and muted colours.
Vec3 plainColour(Draw& draw);

/// Multiplies a mesh's (baked) vertex colours by rgb and drops its texture: a plain object.
void makePlain(render::Mesh* mesh, const Vec3& rgb);

/// The camera in the robot's floor frame (RobotTrajectory::T_w_floor) without vibration: the body
/// at its nominal height, the camera at SimOptions::T_b_c.
SE3 nominalT_floor_c();

/// Share of the image of `camera` covered by a box of full extents size_m at pose T_c_o (camera
/// frame): the convex hull of its projected corners, rasterised at about 160 px wide. Every corner
/// must be in front of the camera (z > 1 cm; otherwise 1 is returned, the view is blocked).
double boxImageShare(const PinholeCamera& camera, const SE3& T_c_o, const Vec3& size_m);

}  // namespace ltlo::sim
