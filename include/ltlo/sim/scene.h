#pragma once
/// The simulated world: a textured room of 8 x 6 x 3 m (x in [-4, 4], y in [-3, 3], z in [0, 3],
/// z up) with static furniture, and the scenario's dynamic boxes with their schedule.
///
/// Textures are collages of real photographs from the installed wallpaper packages (licences in
/// Examples/simulate/README.md: CC-BY(-SA)-4.0 for lomiri-wallpapers, GPL-2+ for mate-backgrounds;
/// they are read at run time, never copied into the repository): every wall panel, floor tile and
/// furniture piece gets its own base photo with framed photo crops pasted at several scales, which
/// gives dense corners at several scales and distinct places. When no photo can be read the same
/// collage is built from procedural multi-scale noise images (logged as a warning).
#include <opencv2/core/mat.hpp>
#include <string>
#include <utility>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/render/offscreen_renderer.h"
#include "ltlo/sim/movers.h"
#include "ltlo/sim/robot_trajectory.h"
#include "ltlo/sim/sim_options.h"

namespace ltlo::sim {

/// A large textured box pushed in front of the robot (or carried by it) during [t_in_s, t_out_s].
struct DynamicBox {
  Vec3 size_m;              ///< full extents (x along the robot's heading, y lateral, z up)
  int texture = -1;         ///< index into Scene::textures
  double t_in_s = 0.0;      ///< starts entering from the side
  double t_out_s = 0.0;     ///< has left at this time
  double enter_s = 1.0;     ///< duration of the slide in (and of the slide out)
  double distance_m = 1.0;  ///< camera-to-near-face distance along the heading while held
  double lateral_m = 0.0;   ///< lateral offset while held (+ = left)
  double side = 1.0;        ///< enters from +1 left / -1 right
  bool crosses = false;     ///< leaves to the other side (-side) instead of back to `side`
  bool carried = false;     ///< rigidly attached to the (vibrating) body while held
  double sway_phase = 0.0;  ///< phase of the small sway of a pushed box
  int event = -1;           ///< scheduling event (the boxes of one event enter and leave together)
  bool panel = false;       ///< a thin board (--plain-movers): size_m = (thickness, width, height)
  bool plain = false;       ///< one colour, no texture (--plain-movers)
  Vec3 plain_rgb = Vec3::Ones();  ///< its colour (0..1) when plain
  StartMove start_move = StartMove::kNone;  ///< --occluded-start: present from t = 0
  double t_move_s = 0.0;    ///< occluded start: held in the floor frame until then, then leaves
};

/// Fixed lighting baked into vertex colours: each triangle is shaded 0.65 + 0.35 |n . l| for one
/// fixed light direction l (view-independent, so a surface looks the same from every view).
/// Triangles must not share vertices across faces of different orientation (true for our quads
/// and boxes).
void bakeFlatShading(render::Mesh* mesh);

/// One rigid part of a mover at a moment: mover index (its mask label is mover + 1), the part's
/// index into Scene::moverMeshes()[mover], and its pose.
struct MoverPart {
  int mover = 0;
  int part = 0;
  SE3 T_w_o;
};

struct Scene {
  std::vector<cv::Mat> textures;            ///< CV_8UC3 BGR; mesh texture ids index this list
  std::vector<render::Mesh> static_meshes;  ///< world frame
  std::vector<render::Mesh> door_frames;    ///< static posts and lintels of the doors (world frame)
  /// Movers, numbered in this order: boxes, walkers, door leaves.
  std::vector<DynamicBox> boxes;
  std::vector<Walker> walkers;
  std::vector<Door> doors;
  bool photo_textures = false;           ///< false: procedural fallback was used
  std::vector<std::string> photo_paths;  ///< photographs used (for the log and stats.txt)

  /// Builds room, furniture and the scenario's occlusion schedule (scene layout fixed; schedule,
  /// box sizes and textures drawn from options.seed).
  static Scene build(const SimOptions& options);
  /// The room and furniture only (the same for every seed and scenario; photos from texture_dir).
  static Scene buildRoom(const std::string& texture_dir);
  /// Replaces the movers with the scenario's occlusion schedule for options.seed and duration and
  /// the options of issue 32's harder worlds (each drawn from its own random stream, so without
  /// them the schedule is what it always was).
  void scheduleOcclusions(const SimOptions& options);
  /// Adds the crossing boxes of options.occlusion_at_s (called by scheduleOcclusions).
  void addCrossingEvents(const SimOptions& options);

  /// Poses of the boxes present at t_s: (index into boxes, T_w_o).
  std::vector<std::pair<int, SE3>> dynamicPoses(double t_s,
                                                const RobotTrajectory& trajectory) const;

  /// Per mover the meshes of its parts in their own frames (shading baked; plain or textured).
  std::vector<std::vector<render::Mesh>> moverMeshes() const;
  /// The parts of every mover present at t_s with their poses, movers in order.
  std::vector<MoverPart> moverParts(double t_s, const RobotTrajectory& trajectory) const;

  /// Static geometry (room, furniture, door frames) as an ASCII PLY (vertices and triangles, world
  /// frame, metres).
  void writePly(const std::string& path) const;
};

}  // namespace ltlo::sim
