#include "ltlo/sim/scene.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <random>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "scene_layout.h"
#include "textures.h"

namespace ltlo::sim {
namespace {

constexpr uint64_t kSceneSeed = 20261122;  // the room is the same in every sequence

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

std::vector<std::vector<render::Mesh>> Scene::moverMeshes() const {
  std::vector<std::vector<render::Mesh>> meshes;
  for (const DynamicBox& box : boxes) {
    render::Mesh mesh = render::makeBoxMesh(box.size_m, box.plain ? -1 : box.texture, 0.0);
    bakeFlatShading(&mesh);
    if (box.plain) makePlain(&mesh, box.plain_rgb);
    meshes.push_back({std::move(mesh)});
  }
  for (const Walker& walker : walkers) meshes.push_back(walkerMeshes(walker));
  for (const Door& door : doors) meshes.push_back({doorLeafMesh(door)});
  return meshes;
}

std::vector<MoverPart> Scene::moverParts(double t_s, const RobotTrajectory& trajectory) const {
  std::vector<MoverPart> parts;
  for (const auto& [index, T_w_o] : dynamicPoses(t_s, trajectory)) parts.push_back({index, 0, T_w_o});
  int mover = static_cast<int>(boxes.size());
  for (const Walker& walker : walkers) {
    if (const std::optional<WalkerState> state = walkerState(walker, t_s, trajectory)) {
      const std::vector<SE3> T_f_p = walkerPartPoses(walker, state->phase_rad);
      for (int part = 0; part < static_cast<int>(T_f_p.size()); ++part)
        parts.push_back({mover, part, state->T_w_f * T_f_p[part]});
    }
    ++mover;
  }
  for (const Door& door : doors) parts.push_back({mover++, 0, doorLeafPose(door, t_s)});
  return parts;
}

Vec3 plainColour(Draw& draw) {
  // Greys and off-whites of painted boards and plastic, muted blue, green, red, ochre, brown.
  static const Vec3 kPalette[] = {
      {0.82, 0.82, 0.80}, {0.62, 0.62, 0.62}, {0.42, 0.42, 0.43}, {0.90, 0.88, 0.82}, {0.45, 0.52, 0.62},
      {0.50, 0.60, 0.50}, {0.66, 0.44, 0.40}, {0.74, 0.64, 0.44}, {0.55, 0.45, 0.35}, {0.58, 0.56, 0.66},
  };
  return kPalette[draw.index(static_cast<int>(std::size(kPalette)))];
}

void makePlain(render::Mesh* mesh, const Vec3& rgb) {
  mesh->texture = -1;
  if (mesh->colours_rgb.empty()) mesh->colours_rgb.assign(mesh->positions_o.size(), Eigen::Vector3f::Ones());
  for (Eigen::Vector3f& colour : mesh->colours_rgb) colour = colour.cwiseProduct(rgb.cast<float>());
}

SE3 nominalT_floor_c() {
  return SE3(Quat::Identity(), Vec3(0, 0, TrajectoryParams{}.body_height_m)) * SimOptions::T_b_c();
}

double boxImageShare(const PinholeCamera& camera, const SE3& T_c_o, const Vec3& size_m) {
  const double factor = std::min(1.0, 160.0 / camera.width());
  const PinholeCamera small = camera.scaled(factor);
  std::vector<cv::Point> corners;
  for (int k = 0; k < 8; ++k) {
    const Vec3 p_o(0.5 * size_m.x() * (k & 1 ? 1 : -1), 0.5 * size_m.y() * (k & 2 ? 1 : -1),
                   0.5 * size_m.z() * (k & 4 ? 1 : -1));
    const Vec3 p_c = T_c_o * p_o;
    if (p_c.z() < 0.01) return 1.0;
    const Vec2 uv = small.project(p_c);
    constexpr double kSub = 16.0;  // 4 fractional bits
    corners.emplace_back(static_cast<int>(std::lround(uv.x() * kSub)), static_cast<int>(std::lround(uv.y() * kSub)));
  }
  std::vector<cv::Point> hull;
  cv::convexHull(corners, hull);
  cv::Mat covered = cv::Mat::zeros(small.height(), small.width(), CV_8U);
  cv::fillConvexPoly(covered, hull, cv::Scalar(255), cv::LINE_8, 4);
  return cv::countNonZero(covered) / static_cast<double>(covered.total());
}

void Scene::writePly(const std::string& path) const {
  std::ofstream out(path);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  std::vector<const render::Mesh*> meshes;
  for (const render::Mesh& mesh : static_meshes) meshes.push_back(&mesh);
  for (const render::Mesh& mesh : door_frames) meshes.push_back(&mesh);
  size_t num_vertices = 0, num_triangles = 0;
  for (const render::Mesh* mesh_ptr : meshes) {
    const render::Mesh& mesh = *mesh_ptr;
    num_vertices += mesh.positions_o.size();
    num_triangles += mesh.triangles.size() / 3;
  }
  out << "ply\nformat ascii 1.0\ncomment LTLO-SLAM simulated room, world frame, metres\n"
      << "element vertex " << num_vertices
      << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "element face " << num_triangles
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const render::Mesh* mesh : meshes)
    for (const Eigen::Vector3f& p : mesh->positions_o)
      out << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  size_t offset = 0;
  for (const render::Mesh* mesh_ptr : meshes) {
    const render::Mesh& mesh = *mesh_ptr;
    for (size_t k = 0; k + 2 < mesh.triangles.size(); k += 3)
      out << "3 " << offset + mesh.triangles[k] << ' ' << offset + mesh.triangles[k + 1] << ' '
          << offset + mesh.triangles[k + 2] << '\n';
    offset += mesh.positions_o.size();
  }
  if (!out) throw InputError(path, 0, "write failed");
}

}  // namespace ltlo::sim
