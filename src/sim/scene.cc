#include "ltlo/sim/scene.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <random>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "textures.h"

namespace ltlo::sim {
namespace {

constexpr uint64_t kSceneSeed = 20261122;  // the room is the same in every sequence
constexpr double kRoomX = 4.0, kRoomY = 3.0, kRoomZ = 3.0;
constexpr double kEnterS = 1.0;  // time a box takes to slide in (and out)
constexpr double kSlideM = 2.5;  // lateral distance it slides over

// Texture index ranges (Scene::textures).
constexpr int kWallPanels = 14, kFloorTextures = 6, kFurnitureTextures = 8, kDynamicTextures = 6;
constexpr int kFirstFloor = kWallPanels, kCeiling = kFirstFloor + kFloorTextures;
constexpr int kFirstFurniture = kCeiling + 1, kFirstDynamic = kFirstFurniture + kFurnitureTextures;

double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

// Quad with corners p0 (uv 0,0), p0 + e_u (1,0), p0 + e_u + e_v (1,1), p0 + e_v (0,1).
render::Mesh quad(const Vec3& p0, const Vec3& e_u, const Vec3& e_v, int texture) {
  render::Mesh mesh;
  mesh.texture = texture;
  for (const Vec3& p : {p0, Vec3(p0 + e_u), Vec3(p0 + e_u + e_v), Vec3(p0 + e_v)})
    mesh.positions_o.push_back(p.cast<float>());
  mesh.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  mesh.triangles = {0, 1, 2, 0, 2, 3};
  return mesh;
}

render::Mesh box(const Vec3& centre_w, const Vec3& size_m, double yaw_rad, int texture) {
  render::Mesh mesh = render::makeBoxMesh(size_m, texture, 1.0);
  const SE3 T_w_o(so3ExpQuat(Vec3(0, 0, yaw_rad)), centre_w);
  for (Eigen::Vector3f& p : mesh.positions_o) p = (T_w_o * p.cast<double>()).cast<float>();
  return mesh;
}

void addTable(std::vector<render::Mesh>* meshes, const Vec2& centre, double yaw, int texture) {
  const SE3 T(so3ExpQuat(Vec3(0, 0, yaw)), Vec3(centre.x(), centre.y(), 0));
  meshes->push_back(box(T * Vec3(0, 0, 0.74), Vec3(1.4, 0.7, 0.04), yaw, texture));
  for (double sx : {-0.65, 0.65})
    for (double sy : {-0.3, 0.3})
      meshes->push_back(box(T * Vec3(sx, sy, 0.36), Vec3(0.05, 0.05, 0.72), yaw, texture));
}

void addShelf(std::vector<render::Mesh>* meshes, const Vec2& centre, double yaw, int texture,
              int back_texture, std::mt19937_64& rng) {
  // Local frame: x along the shelf, y out of the wall (front at -y), z up.
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const SE3 T(so3ExpQuat(Vec3(0, 0, yaw)), Vec3(centre.x(), centre.y(), 0));
  const double w = 1.2, d = 0.36, h = 1.9;
  for (double sx : {-w / 2 + 0.015, w / 2 - 0.015})
    meshes->push_back(box(T * Vec3(sx, 0, h / 2), Vec3(0.03, d, h), yaw, texture));
  meshes->push_back(box(T * Vec3(0, d / 2 - 0.005, h / 2), Vec3(w, 0.01, h), yaw, back_texture));
  for (double z : {0.05, 0.5, 0.95, 1.4, 1.88}) {
    meshes->push_back(box(T * Vec3(0, 0, z), Vec3(w - 0.06, d, 0.025), yaw, texture));
    if (z > 1.8) continue;
    double x = -w / 2 + 0.05;
    while (true) {  // small boxes standing on the board
      const Vec3 size(0.08 + 0.2 * unit(rng), 0.12 + 0.15 * unit(rng), 0.1 + 0.25 * unit(rng));
      if (x + size.x() > w / 2 - 0.05) break;
      const int tex = kFirstFurniture + static_cast<int>(unit(rng) * kFurnitureTextures);
      meshes->push_back(
          box(T * Vec3(x + size.x() / 2, -0.02, z + 0.0125 + size.z() / 2), size, yaw, tex));
      x += size.x() + 0.02 + 0.1 * unit(rng);
    }
  }
}

struct Profile {
  double share, hold_min_s, hold_max_s;
  int max_boxes;
};

}  // namespace

void bakeFlatShading(render::Mesh* mesh) {
  const Eigen::Vector3f light = Eigen::Vector3f(0.35f, 0.55f, 0.75f).normalized();
  mesh->colours_rgb.assign(mesh->positions_o.size(), Eigen::Vector3f::Ones());
  for (size_t k = 0; k + 2 < mesh->triangles.size(); k += 3) {
    const Eigen::Vector3f& a = mesh->positions_o[mesh->triangles[k]];
    const Eigen::Vector3f& b = mesh->positions_o[mesh->triangles[k + 1]];
    const Eigen::Vector3f& c = mesh->positions_o[mesh->triangles[k + 2]];
    const Eigen::Vector3f n = (b - a).cross(c - a).normalized();
    const float shade = 0.65f + 0.35f * std::abs(n.dot(light));
    for (int j = 0; j < 3; ++j) mesh->colours_rgb[mesh->triangles[k + j]].setConstant(shade);
  }
}

Scene Scene::build(const SimOptions& options) {
  Scene scene = buildRoom(options.texture_dir);
  scene.scheduleOcclusions(options);
  return scene;
}

Scene Scene::buildRoom(const std::string& texture_dir) {
  Scene scene;
  std::mt19937_64 rng(kSceneSeed);
  std::vector<cv::Mat> photos = loadPhotos(texture_dir, &scene.photo_paths);
  scene.photo_textures = photos.size() >= 4;
  if (!scene.photo_textures) {
    log::warn("no photographs readable under ", texture_dir,
              "; using procedural multi-scale textures instead");
    photos = proceduralPhotos(12, rng);
    scene.photo_paths.clear();
  }
  const int n = static_cast<int>(photos.size());
  for (int k = 0; k < kWallPanels; ++k)
    scene.textures.push_back(makeCollage(photos, k, cv::Size(640, 960), rng));
  for (int k = 0; k < kFloorTextures; ++k) {
    cv::Mat t = makeCollage(photos, kWallPanels + k, cv::Size(512, 512), rng);
    t.convertTo(t, -1, 0.75, 0);  // floors darker than walls
    scene.textures.push_back(t);
  }
  {
    cv::Mat t = makeCollage(photos, n / 2, cv::Size(512, 512), rng);
    t.convertTo(t, -1, 0.5, 110);  // pale ceiling
    scene.textures.push_back(t);
  }
  for (int k = 0; k < kFurnitureTextures + kDynamicTextures; ++k)
    scene.textures.push_back(makeCollage(photos, 3 * k + 1, cv::Size(512, 512), rng));

  // Walls: 2 m panels, each with its own texture, seen upright from inside the room.
  std::vector<render::Mesh>& m = scene.static_meshes;
  int panel = 0;
  const struct {
    Vec3 top_left;
    Vec3 right;
    double length;
  } walls[] = {{{-kRoomX, kRoomY, kRoomZ}, {1, 0, 0}, 2 * kRoomX},
               {{kRoomX, -kRoomY, kRoomZ}, {-1, 0, 0}, 2 * kRoomX},
               {{kRoomX, kRoomY, kRoomZ}, {0, -1, 0}, 2 * kRoomY},
               {{-kRoomX, -kRoomY, kRoomZ}, {0, 1, 0}, 2 * kRoomY}};
  for (const auto& wall : walls) {
    const int panels = static_cast<int>(std::round(wall.length / 2.0));
    const double width = wall.length / panels;
    for (int k = 0; k < panels; ++k)
      m.push_back(quad(wall.top_left + wall.right * (k * width), wall.right * width,
                       Vec3(0, 0, -kRoomZ), panel++));
  }
  int tile = 0;
  for (double x = -kRoomX; x < kRoomX - 1e-9; x += 2.0)
    for (double y = -kRoomY; y < kRoomY - 1e-9; y += 2.0)
      m.push_back(quad(Vec3(x, y, 0), Vec3(2, 0, 0), Vec3(0, 2, 0),
                       kFirstFloor + (tile++ % kFloorTextures)));
  for (double x = -kRoomX; x < kRoomX - 1e-9; x += 4.0)
    for (double y = -kRoomY; y < kRoomY - 1e-9; y += 3.0)
      m.push_back(quad(Vec3(x, y, kRoomZ), Vec3(4, 0, 0), Vec3(0, 3, 0), kCeiling));

  // Furniture along the walls, clear of the robot's path (|x| < 2.65, |y| < 1.9).
  addTable(&m, Vec2(3.3, -0.8), M_PI / 2, kFirstFurniture + 0);
  addTable(&m, Vec2(-3.3, 0.9), M_PI / 2, kFirstFurniture + 1);
  addShelf(&m, Vec2(-1.5, kRoomY - 0.19), 0.0, kFirstFurniture + 2, kFirstFurniture + 3, rng);
  addShelf(&m, Vec2(1.8, -kRoomY + 0.19), M_PI, kFirstFurniture + 4, kFirstFurniture + 5, rng);
  addShelf(&m, Vec2(kRoomX - 0.19, 1.7), -M_PI / 2, kFirstFurniture + 6, kFirstFurniture + 7, rng);
  m.push_back(box(Vec3(-3.55, -2.55, 0.25), Vec3(0.5, 0.5, 0.5), 0.2, kFirstFurniture + 3));
  m.push_back(box(Vec3(-3.5, -2.6, 0.7), Vec3(0.4, 0.4, 0.4), -0.3, kFirstFurniture + 5));
  m.push_back(box(Vec3(0.6, 2.7, 0.3), Vec3(0.7, 0.45, 0.6), 0.0, kFirstFurniture + 1));
  m.push_back(box(Vec3(-0.6, -2.7, 0.45), Vec3(0.9, 0.45, 0.9), 0.0, kFirstFurniture + 6));
  m.push_back(box(Vec3(3.5, 2.55, 0.35), Vec3(0.6, 0.6, 0.7), 0.4, kFirstFurniture + 0));
  for (render::Mesh& mesh : m) bakeFlatShading(&mesh);
  return scene;
}

void Scene::scheduleOcclusions(const SimOptions& options) {
  Scene& scene = *this;
  scene.boxes.clear();
  std::mt19937_64 event_rng(options.seed * 6364136223846793005ULL + 1442695040888963407ULL);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * unit(event_rng); };
  const double duration = options.duration_s;
  const double t_clear = std::min(3.0, 0.1 * duration);
  auto dynamicTexture = [&]() {
    return kFirstDynamic + static_cast<int>(unit(event_rng) * kDynamicTextures);
  };
  if (options.scenario == Scenario::kCarried) {
    DynamicBox b;
    b.size_m = Vec3(uniform(0.4, 0.6), uniform(0.75, 0.95), uniform(0.8, 0.95));
    b.texture = dynamicTexture();
    b.t_in_s = std::max(t_clear, 0.2 * duration);
    b.t_out_s = 0.85 * duration;
    b.distance_m = uniform(0.65, 0.9);
    b.lateral_m = uniform(-0.15, 0.15);
    b.side = unit(event_rng) < 0.5 ? -1.0 : 1.0;
    b.carried = true;
    b.enter_s = std::min(kEnterS, 0.25 * (b.t_out_s - b.t_in_s));
    scene.boxes.push_back(b);
  } else if (options.scenario != Scenario::kStatic) {
    const Profile profile = options.scenario == Scenario::kStlo   ? Profile{0.17, 2.0, 4.0, 1}
                            : options.scenario == Scenario::kMtlo ? Profile{0.33, 3.0, 6.0, 2}
                                                                  : Profile{0.72, 8.0, 16.0, 3};
    // Per event about hold + kEnterS seconds are largely occluded; gaps fill the rest.
    const double occluded_mean = 0.5 * (profile.hold_min_s + profile.hold_max_s) + kEnterS;
    const double gap_mean =
        std::max(0.5, occluded_mean * (1.0 - profile.share) / profile.share - kEnterS);
    double t = t_clear;
    bool first = true;
    while (true) {
      const double gap = first ? uniform(0.0, 1.0) * gap_mean : uniform(0.6, 1.4) * gap_mean;
      first = false;
      const double t_in = t + gap;
      if (t_in >= duration) break;
      const double t_out = t_in + 2 * kEnterS + uniform(profile.hold_min_s, profile.hold_max_s);
      const int num_boxes = 1 + static_cast<int>(unit(event_rng) * profile.max_boxes);
      DynamicBox front;
      front.size_m = Vec3(uniform(0.5, 0.8), uniform(0.75, 1.1), uniform(0.75, 1.1));
      front.texture = dynamicTexture();
      front.t_in_s = t_in;
      front.t_out_s = t_out;
      front.distance_m = uniform(0.55, 1.05);
      front.lateral_m = uniform(-0.3, 0.3);
      front.side = unit(event_rng) < 0.5 ? -1.0 : 1.0;
      front.sway_phase = uniform(0.0, 2.0 * M_PI);
      scene.boxes.push_back(front);
      for (int k = 1; k < num_boxes; ++k) {  // further boxes behind, peeking out at the sides
        DynamicBox b = front;
        b.size_m = Vec3(uniform(0.5, 0.8), uniform(0.5, 1.0), uniform(0.6, 1.2));
        b.texture = dynamicTexture();
        b.t_in_s = t_in + uniform(0.0, 2.0);
        b.t_out_s = std::max(b.t_in_s + 2 * kEnterS + 1.0, t_out - uniform(0.0, 2.0));
        b.distance_m = front.distance_m + front.size_m.x() + uniform(0.2, 0.6);
        const double sign = k == 1
                                ? (unit(event_rng) < 0.5 ? -1.0 : 1.0)
                                : -1.0 * (scene.boxes.back().lateral_m > front.lateral_m ? 1 : -1);
        b.lateral_m = front.lateral_m + sign * uniform(0.55, 0.9);
        b.side = sign;
        b.sway_phase = uniform(0.0, 2.0 * M_PI);
        scene.boxes.push_back(b);
      }
      t = t_out;
    }
  }
  addCrossingEvents(options);
}

void Scene::addCrossingEvents(const SimOptions& options) {
  for (size_t k = 0; k < options.occlusion_at_s.size(); ++k) {
    // Own stream per event, so the regular schedule's draws stay what they were.
    std::mt19937_64 rng(options.seed * 2862933555777941757ULL + 3037000493ULL * (k + 1));
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * unit(rng); };
    DynamicBox b;
    b.size_m = Vec3(uniform(0.5, 0.8), uniform(0.75, 1.1), uniform(0.75, 1.1));
    b.texture = kFirstDynamic + static_cast<int>(unit(rng) * kDynamicTextures);
    b.t_in_s = options.occlusion_at_s[k];
    b.t_out_s = b.t_in_s + 2 * kEnterS + uniform(2.0, 4.0);
    b.distance_m = uniform(0.55, 1.05);
    b.lateral_m = uniform(-0.2, 0.2);
    b.side = unit(rng) < 0.5 ? -1.0 : 1.0;
    b.crosses = true;
    b.sway_phase = uniform(0.0, 2.0 * M_PI);
    // Regular boxes present while it crosses would stand in its way: they are dropped.
    boxes.erase(std::remove_if(boxes.begin(), boxes.end(),
                               [&](const DynamicBox& other) {
                                 return !other.carried && other.t_in_s < b.t_out_s && other.t_out_s > b.t_in_s;
                               }),
                boxes.end());
    boxes.push_back(b);
  }
}

std::vector<std::pair<int, SE3>> Scene::dynamicPoses(double t_s,
                                                     const RobotTrajectory& trajectory) const {
  std::vector<std::pair<int, SE3>> poses;
  const Vec3 t_b_c = SimOptions::T_b_c().translation();
  for (size_t i = 0; i < boxes.size(); ++i) {
    const DynamicBox& b = boxes[i];
    if (t_s < b.t_in_s || t_s >= b.t_out_s) continue;
    const double slide_in = kSlideM * (1.0 - smoothstep((t_s - b.t_in_s) / b.enter_s));
    const double slide_out = kSlideM * smoothstep((t_s - (b.t_out_s - b.enter_s)) / b.enter_s);
    const double x = t_b_c.x() + b.distance_m + 0.5 * b.size_m.x();
    const double y = b.lateral_m + b.side * slide_in + (b.crosses ? -b.side : b.side) * slide_out;
    if (b.carried) {
      const double z = -trajectory.state(0.0).T_w_b.translation().z() + 0.5 * b.size_m.z() + 0.05;
      const SE3 T_b_o(Quat::Identity(), Vec3(x, y, z));
      poses.emplace_back(static_cast<int>(i), trajectory.state(t_s).T_w_b * T_b_o);
    } else {
      const double p = b.sway_phase;
      const SE3 T_floor_o(so3ExpQuat(Vec3(0, 0, 0.06 * std::sin(0.5 * t_s + 3 * p))),
                          Vec3(x + 0.06 * std::sin(0.9 * t_s + p),
                               y + 0.08 * std::sin(0.6 * t_s + 2 * p), 0.5 * b.size_m.z()));
      poses.emplace_back(static_cast<int>(i), trajectory.T_w_floor(t_s) * T_floor_o);
    }
  }
  return poses;
}

void Scene::writePly(const std::string& path) const {
  std::ofstream out(path);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  size_t num_vertices = 0, num_triangles = 0;
  for (const render::Mesh& mesh : static_meshes) {
    num_vertices += mesh.positions_o.size();
    num_triangles += mesh.triangles.size() / 3;
  }
  out << "ply\nformat ascii 1.0\ncomment LTLO-SLAM simulated room, world frame, metres\n"
      << "element vertex " << num_vertices
      << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "element face " << num_triangles
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const render::Mesh& mesh : static_meshes)
    for (const Eigen::Vector3f& p : mesh.positions_o)
      out << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  size_t offset = 0;
  for (const render::Mesh& mesh : static_meshes) {
    for (size_t k = 0; k + 2 < mesh.triangles.size(); k += 3)
      out << "3 " << offset + mesh.triangles[k] << ' ' << offset + mesh.triangles[k + 1] << ' '
          << offset + mesh.triangles[k + 2] << '\n';
    offset += mesh.positions_o.size();
  }
  if (!out) throw InputError(path, 0, "write failed");
}

}  // namespace ltlo::sim
