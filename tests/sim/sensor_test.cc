// Sensor profiles of the simulator (issue 28): each fault alone on short generated sequences, and the
// ideal profile's output byte for byte against the simulator before profiles.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "ltlo/core/errors.h"
#include "ltlo/core/settings_file.h"
#include "ltlo/sim/simulator.h"

namespace ltlo::sim {
namespace {

namespace fs = std::filesystem;

const Scene& sharedRoom() {
  static const Scene room = Scene::buildRoom(SimOptions().texture_dir);
  return room;
}

std::string stamp6(double t_s) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.6f", t_s);
  return buffer;
}

std::string readFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// FNV-1a, 64 bit: a fingerprint of bytes (not cryptographic; only equality matters here).
uint64_t fnv1a(const std::string& bytes, uint64_t hash = 14695981039346656037ULL) {
  for (unsigned char c : bytes) hash = (hash ^ c) * 1099511628211ULL;
  return hash;
}

// One fingerprint per top-level file and per image folder (its files in name order, names included).
std::map<std::string, std::string> fingerprints(const fs::path& dir) {
  std::map<std::string, uint64_t> hashes;
  std::map<std::string, std::string> files;  // sorted relative paths
  for (const auto& entry : fs::recursive_directory_iterator(dir))
    if (entry.is_regular_file()) files[fs::relative(entry.path(), dir).string()] = entry.path().string();
  for (const auto& [name, path] : files) {
    const size_t slash = name.find('/');
    const std::string group = slash == std::string::npos ? name : name.substr(0, slash + 1);
    auto it = hashes.emplace(group, 14695981039346656037ULL).first;
    it->second = fnv1a(readFile(path), fnv1a(name, it->second));
  }
  std::map<std::string, std::string> text;
  for (const auto& [group, hash] : hashes) {
    char buffer[24];
    std::snprintf(buffer, sizeof(buffer), "%016llx", static_cast<unsigned long long>(hash));
    text[group] = buffer;
  }
  return text;
}

SimOptions smallOptions(Scenario scenario, double seconds, bool noise_free, int width = 160, int height = 120) {
  SimOptions o;
  o.width_px = width;
  o.height_px = height;
  o.scenario = scenario;
  o.seed = 5;
  o.duration_s = seconds;
  o.noise_free = noise_free;
  return o;
}

std::string sourceDir() { return std::getenv("LTLO_SOURCE_DIR") ? std::getenv("LTLO_SOURCE_DIR") : "."; }

SensorProfile shippedProfile(const std::string& name) {
  return SensorProfile::load(SettingsFile(sourceDir() + "/config_yaml/sensor_" + name + ".yaml"));
}

fs::path tempDir(const std::string& name) {
  return fs::temp_directory_path() / ("ltlo_sim_sensor_" + name + "_" + std::to_string(::getpid()));
}

double median(std::vector<double> values) {
  EXPECT_FALSE(values.empty());
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

double quantile(std::vector<double> values, double q) {
  EXPECT_FALSE(values.empty());
  if (values.empty()) return 0.0;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(q * values.size()));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[k];
}

std::vector<std::string> dataLines(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);)
    if (!line.empty() && line[0] != '#') lines.push_back(line);
  return lines;
}

// ---- ray casting against the room (independent of the renderer) ------------------------------

struct Triangle {
  Vec3 a, e1, e2;
};

// The room's triangles per mesh with the mesh's bounding box (rays skip most meshes).
struct MeshTriangles {
  Vec3 lo, hi;
  std::vector<Triangle> triangles;
};
using Room = std::vector<MeshTriangles>;

Room staticTriangles(const Scene& scene) {
  Room room;
  for (const render::Mesh& mesh : scene.static_meshes) {
    MeshTriangles m;
    m.lo = Vec3::Constant(1e30);
    m.hi = Vec3::Constant(-1e30);
    for (const Eigen::Vector3f& p : mesh.positions_o) {
      m.lo = m.lo.cwiseMin(p.cast<double>());
      m.hi = m.hi.cwiseMax(p.cast<double>());
    }
    for (size_t k = 0; k + 2 < mesh.triangles.size(); k += 3) {
      const Vec3 a = mesh.positions_o[mesh.triangles[k]].cast<double>();
      const Vec3 b = mesh.positions_o[mesh.triangles[k + 1]].cast<double>();
      const Vec3 c = mesh.positions_o[mesh.triangles[k + 2]].cast<double>();
      m.triangles.push_back({a, b - a, c - a});
    }
    room.push_back(m);
  }
  return room;
}

// Smallest t > 0 with origin + t dir on a triangle (Moller-Trumbore), infinity when none.
double castRay(const Room& room, const Vec3& origin, const Vec3& dir) {
  double best = std::numeric_limits<double>::infinity();
  for (const MeshTriangles& mesh : room) {
    double t_lo = 0.0, t_hi = best;  // slab test against the mesh's box
    for (int k = 0; k < 3 && t_lo <= t_hi; ++k) {
      if (std::abs(dir[k]) < 1e-15) {
        if (origin[k] < mesh.lo[k] - 1e-9 || origin[k] > mesh.hi[k] + 1e-9) t_lo = t_hi + 1.0;
        continue;
      }
      double t0 = (mesh.lo[k] - 1e-9 - origin[k]) / dir[k], t1 = (mesh.hi[k] + 1e-9 - origin[k]) / dir[k];
      if (t0 > t1) std::swap(t0, t1);
      t_lo = std::max(t_lo, t0);
      t_hi = std::min(t_hi, t1);
    }
    if (t_lo > t_hi) continue;
    for (const Triangle& tri : mesh.triangles) {
      const Vec3 p = dir.cross(tri.e2);
      const double det = tri.e1.dot(p);
      if (std::abs(det) < 1e-12) continue;
      const Vec3 s = origin - tri.a;
      const double u = s.dot(p) / det;
      if (u < 0.0 || u > 1.0) continue;
      const Vec3 q = s.cross(tri.e1);
      const double v = dir.dot(q) / det;
      if (v < 0.0 || u + v > 1.0) continue;
      const double t = tri.e2.dot(q) / det;
      if (t > 1e-6 && t < best) best = t;
    }
  }
  return best;
}

// True z of the room surface seen along raw pixel (u, v) from pose T_w_c (the ray has z = 1 in the
// camera, so the hit's parameter is its z).
double trueDepth(const Room& room, const CameraModel& model, const SE3& T_w_c, int u, int v) {
  const std::optional<Vec3> ray = model.unproject(Vec2(u, v));
  if (!ray) return std::numeric_limits<double>::infinity();
  return castRay(room, T_w_c.translation(), T_w_c.rotationMatrix() * *ray);
}

// ---- the ideal sensor ---------------------------------------------------------------------------

// Fingerprints of the files written by the simulator at commit 4b99cd7 (before sensor profiles) for
// this configuration; the ideal profile, built in or loaded from sensor_ideal.yaml, must reproduce
// them byte for byte. (PNG bytes depend on the platform's zlib/libpng and the photographs installed;
// CI's Debian 12 image is where they were recorded.)
TEST(IdealSensor, OutputIsBitIdenticalToTheSimulatorBeforeSensorProfiles) {
  const std::map<std::string, std::string> expected = {
      {"associations.txt", "5dd09cde58ab0162"}, {"calib.yaml", "2648c6cb6b420c05"},
      {"depth.txt", "2be76c8f13b69091"},        {"depth/", "ac37709851228c53"},
      {"groundtruth.txt", "90b17f8c36da1508"},  {"imu.txt", "d994e57e00d15946"},
      {"imu_biases.txt", "8d9c8ff8e480a115"},   {"masks/", "611cc03eb2df449e"},
      {"rgb.txt", "c161d493031821fe"},          {"rgb/", "b90e8da6dc3e6630"},
      {"scene.ply", "c95812f90d08c575"},        {"stats.txt", "fa78dcadd2160440"},
  };
  SimOptions o = smallOptions(Scenario::kCarried, 0.5, false);
  o.outages.push_back({SensorOutage::Kind::kBlack, 0.1, 0.1});
  o.outages.push_back({SensorOutage::Kind::kImuGap, 0.3, 0.05});
  const SensorProfile shipped_ideal = shippedProfile("ideal");
  EXPECT_TRUE(shipped_ideal.isIdeal());
  for (const SensorProfile& profile : {SensorProfile(), shipped_ideal}) {
    o.sensor = profile;
    const fs::path root = tempDir("ideal");
    Simulator sim(o, sharedRoom());
    writeSequence(sim, root.string(), 0);
    EXPECT_EQ(fingerprints(root), expected) << "profile " << profile.name;
    fs::remove_all(root);
  }
}

// ---- profiles -------------------------------------------------------------------------------------

TEST(SensorProfile, ShippedProfilesLoadWithTheirPresetsAndEveryKeyKnown) {
  for (const char* name : {"ideal", "realsense", "kinect"}) {
    SettingsFile file(sourceDir() + "/config_yaml/sensor_" + std::string(name) + ".yaml");
    const SensorProfile p = SensorProfile::load(file);
    EXPECT_TRUE(file.unreadKeys().empty()) << name << ": " << file.unreadKeys().front();
    EXPECT_EQ(p.name, name);
    EXPECT_FALSE(p.rolling_shutter_enable) << name;  // optional in every profile
  }
  const SensorProfile realsense = shippedProfile("realsense");
  const SensorProfile kinect = shippedProfile("kinect");
  const LensDistortion radtan = lensPreset(LensPreset::kRadTan), rational = lensPreset(LensPreset::kRational);
  EXPECT_EQ(realsense.lens.describe(), radtan.describe());  // --lens radtan is the profile's lens
  EXPECT_EQ(kinect.lens.describe(), rational.describe());
  EXPECT_TRUE(realsense.lens_enable && realsense.imu_clocks_enable && realsense.drops_enable);
  EXPECT_DOUBLE_EQ(realsense.gyro_rate_hz, 200.0);
  EXPECT_DOUBLE_EQ(realsense.acc_rate_hz, 250.0);
  EXPECT_DOUBLE_EQ(kinect.gyro_rate_hz, 1600.0);

  // Magnitudes at the corners of VGA (fx = 525): mild D435-like, strong ~24 px, Azure-like 13 px.
  const PinholeCamera vga(525, 525, 319.5, 239.5, 640, 480);
  auto cornerShiftPx = [&](LensPreset preset) {
    const std::optional<Vec2> ideal = CameraModel(vga, lensPreset(preset)).undistortPixel(Vec2(0, 0));
    return ideal ? ideal->norm() : -1.0;
  };
  EXPECT_NEAR(cornerShiftPx(LensPreset::kRadTan), 2.8, 0.2);
  EXPECT_NEAR(cornerShiftPx(LensPreset::kRadTanStrong), 24.4, 0.5);
  EXPECT_NEAR(cornerShiftPx(LensPreset::kRational), 13.1, 0.3);
  EXPECT_NEAR(cornerShiftPx(LensPreset::kKannalaBrandt), 20.1, 0.5);

  const std::string bad = (fs::temp_directory_path() / "ltlo_sensor_bad.yaml").string();
  std::ofstream(bad) << "%YAML:1.0\nSensor.Drops.Rate: 0.9\n";
  try {
    SensorProfile::load(SettingsFile(bad));
    ADD_FAILURE() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("Sensor.Drops.Rate"), std::string::npos) << e.what();
  }
  fs::remove(bad);
}

// ---- lens ---------------------------------------------------------------------------------------

SensorProfile lensOnly(LensPreset preset) {
  SensorProfile p;
  p.name = "lens";
  p.lens_enable = true;
  p.lens = lensPreset(preset);
  return p;
}

// Corners found in the ideal pinhole image are scene points; in the raw image of the same instant
// they must appear where CameraModel::project puts those points (located there by Lucas-Kanade).
TEST(SensorLens, DistortedColourShowsScenePointsWhereCameraModelProjectsThem) {
  SimOptions o = smallOptions(Scenario::kStatic, 2.0, true, 320, 240);
  Simulator ideal(o, sharedRoom());
  o.sensor = lensOnly(LensPreset::kRadTanStrong);
  Simulator lens(o, sharedRoom());
  const CameraModel model = lens.cameraModel();
  std::vector<double> err_px, pinhole_err_px;
  for (int i : {0, 25, 50}) {
    const SimFrame a = ideal.renderFrame(i), b = lens.renderFrame(i);
    cv::Mat gray_a, gray_b;
    cv::cvtColor(a.bgr, gray_a, cv::COLOR_BGR2GRAY);
    cv::cvtColor(b.bgr, gray_b, cv::COLOR_BGR2GRAY);
    std::vector<cv::Point2f> corners;
    cv::goodFeaturesToTrack(gray_a, corners, 400, 0.01, 6.0);
    cv::cornerSubPix(gray_a, corners, cv::Size(4, 4), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 0.01));
    std::vector<cv::Point2f> ideal_pts, predicted;
    for (const cv::Point2f& c : corners) {
      const float z = a.depth_m.at<float>(cvRound(c.y), cvRound(c.x));
      if (z <= 0.0f) continue;
      const Vec2 u_raw = model.project(ideal.camera().backProject(Vec2(c.x, c.y), z));
      if (!model.pinhole().isInImage(u_raw, 10.0)) continue;
      ideal_pts.push_back(c);
      predicted.emplace_back(static_cast<float>(u_raw.x()), static_cast<float>(u_raw.y()));
    }
    std::vector<cv::Point2f> found = predicted;
    std::vector<uint8_t> status;
    std::vector<float> error;
    cv::calcOpticalFlowPyrLK(gray_a, gray_b, ideal_pts, found, status, error, cv::Size(11, 11), 0,
                             cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 0.001),
                             cv::OPTFLOW_USE_INITIAL_FLOW);
    for (size_t k = 0; k < found.size(); ++k) {
      if (!status[k]) continue;
      err_px.push_back(std::hypot(found[k].x - predicted[k].x, found[k].y - predicted[k].y));
      pinhole_err_px.push_back(std::hypot(found[k].x - ideal_pts[k].x, found[k].y - ideal_pts[k].y));
    }
  }
  ASSERT_GT(err_px.size(), 300u);
  RecordProperty("median_err_px", std::to_string(median(err_px)));
  RecordProperty("p90_err_px", std::to_string(quantile(err_px, 0.9)));
  EXPECT_LT(median(err_px), 0.15);
  EXPECT_LT(quantile(err_px, 0.9), 0.5);
  // Not vacuous: where the pinhole would put them is off by pixels (12 px at these corners).
  EXPECT_GT(quantile(pinhole_err_px, 0.9), 4.0);
}

// Every raw pixel's depth is the z of the room surface its ray (CameraModel::unproject) meets, cast
// against the room's triangles: exactly so (up to the 1 mm steps of the PNG) where the room is one
// plane over the 5 x 5 ideal pixels around the ray's undistorted position (what the sampler reads).
// Near edges the reading keeps the surface of the nearest ideal pixel, moved along it on the axes
// where it is planar: the z of a ray through that pixel or the exact position on each axis, never a
// blend of the two sides of an edge.
TEST(SensorLens, DepthAtRawPixelsIsTheTrueZOfTheSurfaceSeen) {
  SimOptions o = smallOptions(Scenario::kStatic, 2.0, true, 320, 240);
  o.sensor = lensOnly(LensPreset::kRational);
  Simulator sim(o, sharedRoom());
  const CameraModel model = sim.cameraModel();
  const PinholeCamera& pinhole = sim.camera();
  const Room room = staticTriangles(sim.scene());
  const double kQuantum = 0.55e-3;  // half the PNG's millimetre, and a little
  std::vector<double> err_m, planar_err_m;
  int checked = 0, without_depth = 0, blended = 0, edges = 0;
  for (int i : {10, 40}) {
    const SimFrame frame = sim.renderFrame(i);
    const SE3& T_w_c = frame.T_w_c;
    auto zIdeal = [&](double x, double y) {
      return castRay(room, T_w_c.translation(), T_w_c.rotationMatrix() * pinhole.backProject(Vec2(x, y), 1.0));
    };
    for (int v = 2; v < 238; v += 4) {
      for (int u = 2; u < 318; u += 4) {
        const double z_true = trueDepth(room, model, T_w_c, u, v);
        if (!(z_true > o.depth_min_m + 0.01 && z_true < o.depth_max_m - 0.01)) continue;
        ++checked;
        const float z = frame.depth_m.at<float>(v, u);
        if (z <= 0.0f) {
          ++without_depth;
          continue;
        }
        err_m.push_back(std::abs(z - z_true));
        const Vec2 ideal = *model.undistortPixel(Vec2(u, v));
        const double x0 = std::round(ideal.x()), y0 = std::round(ideal.y());
        double w[5][5];
        for (int dy = -2; dy <= 2; ++dy)
          for (int dx = -2; dx <= 2; ++dx) w[dy + 2][dx + 2] = 1.0 / zIdeal(x0 + dx, y0 + dy);
        bool planar = true;  // 1/z of a plane is linear in the pixel coordinates
        for (int r = 0; r < 5; ++r)
          for (int c = 0; c < 5; ++c) {
            const double w_plane = w[2][2] + (c - 2) * 0.5 * (w[2][3] - w[2][1]) + (r - 2) * 0.5 * (w[3][2] - w[1][2]);
            planar = planar && std::abs(w[r][c] - w_plane) < 1e-5;
          }
        if (planar) {
          planar_err_m.push_back(std::abs(z - z_true));
          continue;
        }
        ++edges;
        bool on_a_ray = false;
        for (double x : {ideal.x(), x0})
          for (double y : {ideal.y(), y0}) on_a_ray = on_a_ray || std::abs(z - zIdeal(x, y)) <= kQuantum;
        blended += !on_a_ray;
      }
    }
  }
  ASSERT_GT(checked, 7000);
  const double share_within =
      std::count_if(err_m.begin(), err_m.end(), [&](double e) { return e <= kQuantum; }) / static_cast<double>(err_m.size());
  RecordProperty("median_err_mm", std::to_string(1e3 * median(planar_err_m)));
  RecordProperty("share_within_0_55mm", std::to_string(share_within));
  RecordProperty("edge_pixels", edges);
  EXPECT_EQ(without_depth, 0);
  EXPECT_GT(planar_err_m.size(), static_cast<size_t>(0.7 * checked));
  EXPECT_LT(median(planar_err_m), 0.3e-3);
  EXPECT_LT(quantile(planar_err_m, 1.0), kQuantum);
  EXPECT_GT(share_within, 0.95);
  EXPECT_GT(edges, 50);  // there are edges to get wrong
  EXPECT_EQ(blended, 0);
}

// The mask is the visible dynamic surface in the raw grid: where the box (rendered alone through the
// same lens) is nearer than the room (alone).
TEST(SensorLens, MasksMarkTheVisibleDynamicSurfaceInTheRawGrid) {
  SimOptions o = smallOptions(Scenario::kCarried, 2.0, true);
  o.sensor = lensOnly(LensPreset::kRational);
  Simulator sim(o, sharedRoom());
  int wrong = 0, dynamic_pixels = 0;
  for (int i : {20, 35, 50}) {
    const SimFrame frame = sim.renderFrame(i);
    const render::RenderResult dynamic = sim.renderDynamicOnly(i), room = sim.renderStaticOnly(i);
    ASSERT_EQ(dynamic.labels.size(), frame.mask.size());
    for (int v = 0; v < frame.mask.rows; ++v)
      for (int u = 0; u < frame.mask.cols; ++u) {
        const float zd = dynamic.depth_m.at<float>(v, u), zs = room.depth_m.at<float>(v, u);
        const bool expected = zd > 0 && (zs == 0 || zd < zs);
        dynamic_pixels += expected;
        wrong += expected != (frame.mask.at<uint8_t>(v, u) == 255);
      }
  }
  EXPECT_GT(dynamic_pixels, 3 * 160 * 120 / 5);
  EXPECT_EQ(wrong, 0);
}

TEST(SensorLens, CalibYamlDescribesTheLens) {
  SimOptions o = smallOptions(Scenario::kStatic, 0.2, true);
  o.sensor = lensOnly(LensPreset::kRational);
  const fs::path root = tempDir("lens_calib");
  Simulator sim(o, sharedRoom());
  writeSequence(sim, root.string(), 0);
  const SensorCalib calib = SensorCalib::load((root / "calib.yaml").string());
  EXPECT_EQ(calib.camera.lens.describe(), lensPreset(LensPreset::kRational).describe());
  EXPECT_DOUBLE_EQ(calib.imu.time_offset_s, 0.0);
  const cv::FileStorage truth((root / "sensor_truth.yaml").string(), cv::FileStorage::READ);
  EXPECT_EQ(static_cast<std::string>(truth["Truth.Lens.Model"]), "rational");
  EXPECT_DOUBLE_EQ(static_cast<double>(truth["Truth.Lens.k5"]), lensPreset(LensPreset::kRational).k5);
  fs::remove_all(root);
}

// ---- time offset, extrinsic, IMU intrinsics -----------------------------------------------------

TEST(SensorImu, TimeOffsetShowsInTheImuStamps) {
  SimOptions o = smallOptions(Scenario::kStatic, 1.0, true);
  o.sensor.name = "offset";
  o.sensor.time_offset_enable = true;
  o.sensor.time_offset_s = 0.0123;  // not a multiple of the 5 ms period
  Simulator sim(o, sharedRoom());
  const RobotTrajectory& trajectory = sim.trajectory();
  double err_with_offset = 0.0, err_without = 0.0;
  for (const ImuSample& s : sim.imu()) {
    // Kalibr: t_imu = t_cam + offset, so the sample stamped t measured the instant t - offset.
    err_with_offset = std::max(err_with_offset, (s.gyro_rad_s - trajectory.state(s.t_s - 0.0123).omega_b).norm());
    err_without += (s.gyro_rad_s - trajectory.state(s.t_s).omega_b).norm() / sim.imu().size();
    EXPECT_NEAR(s.t_true_s, s.t_s - 0.0123, 1e-12);
  }
  EXPECT_LT(err_with_offset, 1e-12);
  EXPECT_GT(err_without, 1e-3);  // 12 ms of the 0.5-3 Hz vibration
  EXPECT_NEAR(sim.imu()[200].t_s, 1.0, 1e-12);  // the IMU's own clock still covers [0, 1] s

  const fs::path root = tempDir("offset");
  writeSequence(sim, root.string(), 0);
  // The text: row k is "k/200 ..." with the rate of the instant k/200 - 0.0123.
  const std::vector<std::string> rows = dataLines(root / "imu.txt");
  ASSERT_EQ(rows.size(), 201u);
  double t = 0, gx = 0, gy = 0, gz = 0;
  ASSERT_EQ(std::sscanf(rows[40].c_str(), "%lf %lf %lf %lf", &t, &gx, &gy, &gz), 4);
  EXPECT_NEAR(t, 0.2, 1e-9);
  EXPECT_LT((Vec3(gx, gy, gz) - trajectory.state(0.2 - 0.0123).omega_b).norm(), 2e-9);
  EXPECT_DOUBLE_EQ(SensorCalib::load((root / "calib.yaml").string()).imu.time_offset_s, 0.0);  // unknown
  fs::remove_all(root);

  o.sensor.time_offset_in_calib = true;
  Simulator told(o, sharedRoom());
  EXPECT_DOUBLE_EQ(told.calib().imu.time_offset_s, 0.0123);
}

TEST(SensorImu, CalibExtrinsicIsOffByTheProfilesMagnitudeInASeededDirection) {
  SensorProfile p;
  p.name = "extrinsic";
  p.extrinsic_enable = true;
  p.extrinsic_translation_m = 0.003;
  p.extrinsic_rotation_deg = 0.2;
  const std::vector<double> frames = {0.0};
  const SE3 T_b_c = SimOptions::T_b_c();
  const SensorTruth a = drawSensorTruth(p, 1, T_b_c, 200.0, frames), a2 = drawSensorTruth(p, 1, T_b_c, 200.0, frames),
                    b = drawSensorTruth(p, 2, T_b_c, 200.0, frames);
  const SE3 T_c_ce = T_b_c.inverse() * a.T_b_c_calib;
  EXPECT_NEAR(T_c_ce.translation().norm(), 0.003, 1e-12);
  EXPECT_NEAR(so3Log(T_c_ce.rotationMatrix()).norm() * 180.0 / M_PI, 0.2, 1e-9);
  EXPECT_NEAR((a.T_b_c_calib.translation() - T_b_c.translation()).norm(), 0.003, 1e-12);
  EXPECT_EQ(a.T_b_c_calib.matrix(), a2.T_b_c_calib.matrix());            // same seed, same error
  EXPECT_GT((a.T_b_c_calib.matrix() - b.T_b_c_calib.matrix()).norm(), 1e-4);  // another seed, another
  EXPECT_EQ(a.T_b_c.matrix(), T_b_c.matrix());
}

TEST(SensorImu, ScaleAndMisalignmentMultiplyTheTrueReadings) {
  SimOptions o = smallOptions(Scenario::kStatic, 0.5, true);
  o.sensor = shippedProfile("ideal");
  o.sensor.imu_intrinsics_enable = true;  // 0.35 % each, from the profile
  Simulator sim(o, sharedRoom());
  const SensorTruth& truth = sim.sensorTruth();
  for (const Mat3* M : {&truth.M_gyro, &truth.M_acc}) {
    for (int i = 0; i < 3; ++i) {
      EXPECT_GE(std::abs((*M)(i, i) - 1.0), 0.6 * 0.0035 - 1e-6);
      EXPECT_LE(std::abs((*M)(i, i) - 1.0), 1.4 * 0.0035 + 2e-5);
    }
    for (auto [r, c] : {std::pair{1, 0}, {2, 0}, {2, 1}}) {
      EXPECT_GE(std::abs((*M)(r, c)), 0.6 * 0.0035 * 0.99);
      EXPECT_LE(std::abs((*M)(r, c)), 1.4 * 0.0035 * 1.01);
    }
  }
  const Vec3 g_w(0, 0, -kGravityMps2);
  for (const ImuSample& s : sim.imu()) {
    const RobotState state = sim.trajectory().state(s.t_s);
    EXPECT_LT((s.gyro_rad_s - truth.M_gyro * state.omega_b).norm(), 1e-12);
    EXPECT_LT((s.acc_mps2 - truth.M_acc * (state.T_w_b.rotationMatrix().transpose() * (state.a_w_b - g_w))).norm(),
              1e-12);
  }
}

// ---- clocks and jitter ----------------------------------------------------------------------------

struct ImuRows {
  std::vector<double> gyro_t, acc_t, full_t;
  int bad = 0;  ///< rows that are neither half nor full
  bool increasing = true;
};

ImuRows parseImuRows(const fs::path& path) {
  ImuRows rows;
  double previous = -1.0;
  for (const std::string& line : dataLines(path)) {
    std::istringstream in(line);
    double t;
    std::string v[6];
    in >> t >> v[0] >> v[1] >> v[2] >> v[3] >> v[4] >> v[5];
    const bool gyro_nan = v[0] == "nan" && v[1] == "nan" && v[2] == "nan";
    const bool acc_nan = v[3] == "nan" && v[4] == "nan" && v[5] == "nan";
    const bool any_nan = line.find("nan") != std::string::npos;
    if (!any_nan) rows.full_t.push_back(t);
    else if (acc_nan && !gyro_nan && v[0].find("nan") == std::string::npos) rows.gyro_t.push_back(t);
    else if (gyro_nan && !acc_nan && v[3].find("nan") == std::string::npos) rows.acc_t.push_back(t);
    else ++rows.bad;
    rows.increasing = rows.increasing && t > previous;
    previous = t;
  }
  return rows;
}

std::vector<double> differences(const std::vector<double>& t) {
  std::vector<double> d;
  for (size_t i = 1; i < t.size(); ++i) d.push_back(t[i] - t[i - 1]);
  return d;
}

TEST(SensorImu, SeparateClocksWriteHalfRowsAtEachSensorsRate) {
  SimOptions o = smallOptions(Scenario::kStatic, 2.0, false);
  o.sensor = shippedProfile("ideal");
  o.sensor.imu_clocks_enable = true;  // gyro 200 Hz, accel 250 Hz
  const fs::path root = tempDir("clocks");
  {
    Simulator sim(o, sharedRoom());
    writeSequence(sim, root.string(), 0);
  }
  const ImuRows rows = parseImuRows(root / "imu.txt");
  EXPECT_EQ(rows.bad, 0);
  EXPECT_TRUE(rows.full_t.empty());
  EXPECT_TRUE(rows.increasing);
  EXPECT_EQ(rows.gyro_t.size(), 401u);                       // k / 200 for k = 0 .. 400
  EXPECT_NEAR(static_cast<double>(rows.acc_t.size()), 500.5, 0.6);  // phase + j / 250 within [0, 2]
  EXPECT_NEAR(median(differences(rows.gyro_t)), 0.005, 1e-6);
  EXPECT_NEAR(median(differences(rows.acc_t)), 0.004, 1e-6);
  EXPECT_EQ(dataLines(root / "imu_biases.txt").size(), rows.gyro_t.size() + rows.acc_t.size());
  const SensorCalib calib = SensorCalib::load((root / "calib.yaml").string());
  EXPECT_DOUBLE_EQ(calib.imu.rate_hz, 200.0);
  fs::remove_all(root);

  // Merged rows: full rows at the gyro stamps, the accelerometer interpolated onto them.
  o.noise_free = true;
  o.sensor.merged_rows = true;
  Simulator merged(o, sharedRoom());
  const Vec3 g_w(0, 0, -kGravityMps2);
  double worst_acc = 0.0;
  for (const ImuSample& s : merged.imu()) {
    ASSERT_TRUE(s.has_gyro && s.has_acc);
    const RobotState state = merged.trajectory().state(s.t_s);
    worst_acc = std::max(worst_acc,
                         (s.acc_mps2 - state.T_w_b.rotationMatrix().transpose() * (state.a_w_b - g_w)).norm());
  }
  EXPECT_GE(merged.imu().size(), 399u);  // gyro stamps outside the accelerometer's span are left out
  EXPECT_LT(worst_acc, 5e-3);            // linear interpolation over 4 ms of the vibration
}

TEST(SensorJitter, StampsScatterAroundTheTrueInstantsAndTheGroundTruthKeepsTheTruePose) {
  SimOptions o = smallOptions(Scenario::kStatic, 20.0, true);
  o.sensor = shippedProfile("ideal");
  o.sensor.jitter_enable = true;  // camera 0.3 ms, IMU 0.2 ms
  Simulator sim(o, sharedRoom());
  double sum_sq = 0.0, worst = 0.0;
  for (int i = 0; i < sim.numFrames(); ++i) {
    const double d = sim.frameStamp(i) - sim.frameTime(i);
    sum_sq += d * d;
    worst = std::max(worst, std::abs(d));
  }
  RecordProperty("camera_jitter_std_ms", std::to_string(1e3 * std::sqrt(sum_sq / sim.numFrames())));
  EXPECT_NEAR(std::sqrt(sum_sq / sim.numFrames()), 3.0e-4, 0.3e-4);
  EXPECT_LE(worst, 9.0e-4 + 1e-6);  // clipped at 3 sigma
  double imu_sq = 0.0;
  for (size_t k = 0; k < sim.imu().size(); ++k) imu_sq += std::pow(sim.imu()[k].t_s - k / o.imu_rate_hz, 2);
  RecordProperty("imu_jitter_std_ms", std::to_string(1e3 * std::sqrt(imu_sq / sim.imu().size())));
  EXPECT_NEAR(std::sqrt(imu_sq / sim.imu().size()), 2.0e-4, 0.15e-4);
  // Ground truth by stamp: the pose of the instant the image was really taken.
  const io::Trajectory gt = sim.groundTruth();
  ASSERT_EQ(gt.size(), static_cast<size_t>(sim.numFrames()));
  for (int i = 0; i < sim.numFrames(); i += 50) {
    EXPECT_EQ(gt[i].t_s, sim.frameStamp(i));
    EXPECT_LT((gt[i].T_w_x.matrix() - sim.T_w_c(sim.frameTime(i)).matrix()).norm(), 1e-12);
  }
}

// ---- exposure and dropped frames ----------------------------------------------------------------

TEST(SensorExposure, StepsAreAFewPerMinuteOfFifteenToThirtyPercent) {
  const SensorProfile p = shippedProfile("realsense");
  std::vector<double> frames(18000);  // 10 minutes at 30 Hz
  for (size_t i = 0; i < frames.size(); ++i) frames[i] = i / 30.0;
  const SensorTruth truth = drawSensorTruth(p, 3, SimOptions::T_b_c(), 200.0, frames);
  EXPECT_GE(truth.exposure_steps.size(), 22u);  // Poisson, mean 40
  EXPECT_LE(truth.exposure_steps.size(), 60u);
  double lo = 1e9, hi = 0.0;
  for (const ExposureStep& step : truth.exposure_steps) {
    const double size = step.ratio > 1.0 ? step.ratio - 1.0 : 1.0 / step.ratio - 1.0;
    EXPECT_GE(size, 0.15 - 1e-12);
    EXPECT_LE(size, 0.30 + 1e-12);
    // Over the ramp the gain moves from the level before to the level after.
    const double before = truth.exposureGain(step.t_s - 1e-9), after = truth.exposureGain(step.t_s + p.exposure_ramp_s);
    EXPECT_NEAR(after / before, step.ratio, 0.01);
  }
  for (double t : frames) {
    lo = std::min(lo, truth.exposureGain(t));
    hi = std::max(hi, truth.exposureGain(t));
  }
  EXPECT_GT(lo, 0.4);
  EXPECT_LT(hi, 2.5);
}

TEST(SensorExposure, ColourCarriesEachFramesGainAndDepthIsUntouched) {
  SimOptions o = smallOptions(Scenario::kStatic, 6.0, true);
  Simulator plain(o, sharedRoom());
  o.sensor.name = "exposure";
  o.sensor.exposure_enable = true;
  o.sensor.exposure_steps_per_min = 40.0;  // several steps within the 6 s
  o.sensor.exposure_ramp_s = 0.3;
  o.sensor.exposure_drift = 0.05;
  Simulator exposed(o, sharedRoom());
  double largest_change = 0.0, worst_gain_err = 0.0;
  for (int i = 0; i < exposed.numFrames(); i += 15) {
    const SimFrame a = plain.renderFrame(i), b = exposed.renderFrame(i);
    EXPECT_NEAR(b.gain, exposed.sensorTruth().exposureGain(b.t_true_s), 1e-6);
    EXPECT_EQ(cv::norm(a.depth_raw, b.depth_raw, cv::NORM_INF), 0.0);
    // Gain measured on pixels saturated in neither image.
    double sum_a = 0.0, sum_b = 0.0;
    int saturated_b = 0, saturated_a = 0;
    for (int v = 0; v < a.bgr.rows; ++v)
      for (int u = 0; u < a.bgr.cols; ++u)
        for (int c = 0; c < 3; ++c) {
          const int pa = a.bgr.at<cv::Vec3b>(v, u)[c], pb = b.bgr.at<cv::Vec3b>(v, u)[c];
          saturated_a += pa == 255;
          saturated_b += pb == 255;
          if (pa < 250 && pb < 250 && pa > 20) {
            sum_a += pa;
            sum_b += pb;
          }
        }
    EXPECT_NEAR(sum_b / sum_a, b.gain, 0.01) << "frame " << i;
    worst_gain_err = std::max(worst_gain_err, std::abs(sum_b / sum_a - b.gain));
    if (b.gain > 1.05) {
      EXPECT_GE(saturated_b, saturated_a);  // brighter saturates, never wraps
    }
    largest_change = std::max(largest_change, std::abs(b.gain - 1.0));
  }
  RecordProperty("largest_gain_change", std::to_string(largest_change));
  RecordProperty("worst_measured_gain_error", std::to_string(worst_gain_err));
  EXPECT_GT(largest_change, 0.12);  // not vacuous
}

TEST(SensorDrops, OneToThreePercentInBurstsOfOneToThree) {
  const SensorProfile p = shippedProfile("realsense");  // 2 %, bursts of 1-3
  std::vector<double> frames(18000);
  for (size_t i = 0; i < frames.size(); ++i) frames[i] = i / 30.0;
  const SensorTruth truth = drawSensorTruth(p, 4, SimOptions::T_b_c(), 200.0, frames);
  int dropped = 0, bursts = 0, longest = 0, run = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    dropped += truth.dropped[i];
    run = truth.dropped[i] ? run + 1 : 0;
    bursts += truth.dropped[i] && (i == 0 || !truth.dropped[i - 1]);
    longest = std::max(longest, run);
  }
  const double share = dropped / static_cast<double>(frames.size());
  RecordProperty("dropped_share", std::to_string(share));
  EXPECT_GT(share, 0.016);
  EXPECT_LT(share, 0.024);
  EXPECT_LE(longest, 3);
  EXPECT_NEAR(dropped / static_cast<double>(bursts), 2.0, 0.15);  // uniform 1..3
  EXPECT_EQ(truth.dropped[0], 0);
}

TEST(SensorDrops, DroppedFramesAreMissingFromTheListsWhileTheImuRunsOn) {
  SimOptions o = smallOptions(Scenario::kStatic, 2.0, true);
  o.sensor.name = "drops";
  o.sensor.drops_enable = true;
  o.sensor.drop_rate = 0.15;
  o.sensor.drop_max_burst = 3;
  const fs::path root = tempDir("drops");
  Simulator sim(o, sharedRoom());
  const SequenceStats stats = writeSequence(sim, root.string(), 0);
  int dropped = 0;
  for (int i = 0; i < sim.numFrames(); ++i) dropped += sim.frameDropped(i);
  ASSERT_GT(dropped, 3);
  EXPECT_EQ(stats.num_dropped, dropped);
  EXPECT_EQ(stats.num_frames, sim.numFrames() - dropped);
  for (const char* list : {"rgb.txt", "depth.txt", "associations.txt", "groundtruth.txt"})
    EXPECT_EQ(dataLines(root / list).size(), static_cast<size_t>(stats.num_frames)) << list;
  EXPECT_EQ(static_cast<size_t>(std::distance(fs::directory_iterator(root / "rgb"), fs::directory_iterator())),
            static_cast<size_t>(stats.num_frames));
  EXPECT_EQ(dataLines(root / "imu.txt").size(), 401u);  // every IMU sample of the 2 s
  const cv::FileStorage truth((root / "sensor_truth.yaml").string(), cv::FileStorage::READ);
  EXPECT_EQ(static_cast<int>(truth["Truth.Frames.Dropped"].size()), dropped);
  EXPECT_EQ(static_cast<int>(truth["Truth.Frames.Gain"].size()), stats.num_frames);
  for (const cv::FileNode& index : truth["Truth.Frames.Dropped"]) {
    EXPECT_TRUE(sim.frameDropped(static_cast<int>(index)));
    EXPECT_FALSE(fs::exists(root / "rgb" / (stamp6(sim.frameStamp(static_cast<int>(index))) + ".png")));
  }
  fs::remove_all(root);
}

// ---- rolling shutter --------------------------------------------------------------------------------

// Each band of rows sees the room from the pose of its own time: depth agrees with the ray cast from
// the band's pose, not from the frame's (centre) pose for the outer bands.
TEST(SensorRollingShutter, RowsSeeTheRoomFromThePoseOfTheirOwnTime) {
  SimOptions o = smallOptions(Scenario::kStatic, 2.0, true);
  o.sensor.name = "rolling";
  o.sensor.rolling_shutter_enable = true;
  o.sensor.readout_s = 0.030;
  o.sensor.rolling_shutter_bands = 4;
  o.sensor.lens_enable = true;
  o.sensor.lens = lensPreset(LensPreset::kRadTan);
  Simulator sim(o, sharedRoom());
  const CameraModel model = sim.cameraModel();
  const Room room = staticTriangles(sim.scene());
  const int i = 30, height = 120, band_rows = height / 4;
  const SimFrame frame = sim.renderFrame(i);
  std::vector<double> err_band, err_centre_outer;
  for (int band = 0; band < 4; ++band) {
    const double centre_row = band * band_rows + 0.5 * (band_rows - 1);
    const double t_band = frame.t_true_s + (centre_row - 0.5 * (height - 1)) * o.sensor.readout_s / (height - 1);
    for (int v = band * band_rows; v < (band + 1) * band_rows; v += 2) {
      for (int u = 0; u < 160; u += 2) {
        const float z = frame.depth_m.at<float>(v, u);
        if (z <= 0.0f) continue;
        const double z_band = trueDepth(room, model, sim.T_w_c(t_band), u, v);
        const double z_centre = trueDepth(room, model, sim.T_w_c(frame.t_true_s), u, v);
        if (!std::isfinite(z_band) || !std::isfinite(z_centre)) continue;
        err_band.push_back(std::abs(z - z_band));
        if (band == 0 || band == 3) err_centre_outer.push_back(std::abs(z - z_centre));
      }
    }
  }
  ASSERT_GT(err_band.size(), 3000u);
  RecordProperty("median_err_band_pose_mm", std::to_string(1e3 * median(err_band)));
  RecordProperty("median_err_centre_pose_outer_bands_mm", std::to_string(1e3 * median(err_centre_outer)));
  EXPECT_LT(median(err_band), 0.3e-3);
  EXPECT_GT(median(err_centre_outer), 1.5e-3);  // 11 ms of travel at ~0.45 m/s: several mm
}
}  // namespace
}  // namespace ltlo::sim
