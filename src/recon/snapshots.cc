#include "ltlo/recon/snapshots.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/render/look_at.h"
#include "ltlo/render/offscreen_renderer.h"
#include "picture_drawing.h"

namespace ltlo::recon {
namespace {

using render::lookAt;

constexpr double kBirdEyeFovDeg = 40.0;  // narrow: close to a map's orthographic look
constexpr double kOrbitElevationDeg = 35.0;
constexpr float kAmbient = 0.35f;  // headlight shading: colour * (0.35 + 0.65 |cos|)
// Discs are drawn 25 % larger than fused: a disc spans its pixel's footprint at the distance it
// was made from, so views from elsewhere show pinholes between neighbours without it.
constexpr float kDisplayRadiusScale = 1.25f;
const Eigen::Vector3f kBackground(0.10f, 0.10f, 0.12f);
const cv::Scalar kEstimateBgr(40, 60, 235);     // red
const cv::Scalar kGroundTruthBgr(80, 210, 80);  // green

// World <-> display frame d: z up, x along the model's longest horizontal extent.
struct DisplayFrame {
  Mat3 R_w_d;       // columns: display axes in the world
  Vec3 lo_d, hi_d;  // robust bounds of the model in display coordinates
  Vec3 toWorld(const Vec3& p_d) const { return R_w_d * p_d; }
  Vec3 axis(int k) const { return R_w_d.col(k); }
};

double percentileOf(std::vector<double> values, double fraction) {
  if (values.empty()) return 0.0;
  const std::size_t k =
      std::min(values.size() - 1, static_cast<std::size_t>(fraction * values.size()));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[k];
}

// The horizontal direction (orthogonal to `up`) that most wall surfels face, modulo 90 deg: a
// histogram of the angles of their horizontal normals in 1 deg bins (smoothed over +-2 bins),
// weighted by area. Empty when fewer than 1000 surfels stand upright.
std::optional<Vec3> dominantWallAxis(const std::vector<Surfel>& surfels, const Vec3& up,
                                     const Vec3& x0) {
  const Vec3 y0 = up.cross(x0);
  std::vector<double> histogram(90, 0.0);
  int upright = 0;
  for (const Surfel& s : surfels) {
    const Vec3 n = s.normal_w.cast<double>();
    if (std::abs(n.dot(up)) > 0.3) continue;
    double angle_deg = std::atan2(n.dot(y0), n.dot(x0)) * 180.0 / M_PI;
    angle_deg = std::fmod(angle_deg + 360.0, 90.0);
    histogram[static_cast<int>(angle_deg) % 90] += s.radius_m * s.radius_m;
    ++upright;
  }
  if (upright < 1000) return std::nullopt;
  int best = 0;
  double best_score = -1.0;
  for (int b = 0; b < 90; ++b) {
    double score = 0.0;
    for (int d = -2; d <= 2; ++d) score += histogram[(b + d + 90) % 90];
    if (score > best_score) {
      best_score = score;
      best = b;
    }
  }
  const double a = (best + 0.5) * M_PI / 180.0;
  return Vec3(std::cos(a) * x0 + std::sin(a) * y0);
}

DisplayFrame displayFrame(const std::vector<Surfel>& surfels, const io::Trajectory& trajectory) {
  const Vec3 up = estimateUpDirection(trajectory);
  std::vector<Vec3> points;
  const std::size_t step = std::max<std::size_t>(1, surfels.size() / 200000);
  for (std::size_t i = 0; i < surfels.size(); i += step) {
    points.push_back(surfels[i].position_w.cast<double>());
  }
  if (points.size() < 10) {
    for (const io::StampedPose& pose : trajectory) points.push_back(pose.T_w_x.translation());
  }
  // Principal horizontal direction.
  Vec3 mean = Vec3::Zero();
  for (const Vec3& p : points) mean += p;
  mean /= std::max<std::size_t>(1, points.size());
  Mat3 cov = Mat3::Zero();
  for (const Vec3& p : points) {
    const Vec3 h = (p - mean) - up * up.dot(p - mean);
    cov += h * h.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Mat3> eig(cov);
  Vec3 x = eig.eigenvectors().col(2);
  x = (x - up * up.dot(x));
  if (x.norm() < 1e-9) x = up.unitOrthogonal();
  x.normalize();
  // Rooms are mostly rectangular: turn x onto the dominant wall direction when walls exist.
  if (const std::optional<Vec3> wall_axis = dominantWallAxis(surfels, up, x)) x = *wall_axis;
  DisplayFrame frame;
  frame.R_w_d.col(0) = x;
  frame.R_w_d.col(1) = up.cross(x);
  frame.R_w_d.col(2) = up;
  std::vector<double> coords[3];
  for (const Vec3& p : points) {
    const Vec3 d = frame.R_w_d.transpose() * p;
    for (int k = 0; k < 3; ++k) coords[k].push_back(d[k]);
  }
  for (const io::StampedPose& pose : trajectory) {  // the path is always in the picture
    const Vec3 d = frame.R_w_d.transpose() * pose.T_w_x.translation();
    for (int k = 0; k < 3; ++k) coords[k].push_back(d[k]);
  }
  for (int k = 0; k < 3; ++k) {
    frame.lo_d[k] = percentileOf(coords[k], 0.005);
    frame.hi_d[k] = percentileOf(coords[k], 0.995);
  }
  if (frame.hi_d.y() - frame.lo_d.y() > frame.hi_d.x() - frame.lo_d.x()) {
    // The longer side along x (landscape pictures): turn the display frame by 90 deg about up.
    frame.R_w_d.col(0) = frame.R_w_d.col(1);
    frame.R_w_d.col(1) = up.cross(Vec3(frame.R_w_d.col(0)));
    std::swap(coords[0], coords[1]);
    for (double& y : coords[1]) y = -y;
  }
  for (int k = 0; k < 3; ++k) {
    frame.lo_d[k] = percentileOf(coords[k], 0.005);
    frame.hi_d[k] = percentileOf(coords[k], 0.995);
    if (frame.hi_d[k] - frame.lo_d[k] < 0.5) {  // a flat or empty model: at least 0.5 m
      const double centre = 0.5 * (frame.hi_d[k] + frame.lo_d[k]);
      frame.lo_d[k] = centre - 0.25;
      frame.hi_d[k] = centre + 0.25;
    }
  }
  return frame;
}

struct View {
  std::string name;   // file stem
  std::string label;  // text on the picture
  PinholeCamera camera;
  SE3 T_c_w;
  double far_m = 50.0;
};

cv::Point projectToImage(const PinholeCamera& camera, const SE3& T_c_w, const Vec3& p_w,
                         bool* in_front) {
  const Vec3 p_c = T_c_w * p_w;
  *in_front = p_c.z() > 0.05;
  const Vec2 u = camera.project(p_c);
  return cv::Point(static_cast<int>(std::lround(u.x() * 4)),
                   static_cast<int>(std::lround(u.y() * 4)));
}

// Polyline of the trajectory's positions (shift 2: quarter-pixel precision, anti-aliased).
// The ground truth is drawn wider, underneath: it shows as a border around a close estimate.
void drawPath(cv::Mat* image, const PinholeCamera& camera, const SE3& T_c_w,
              const io::Trajectory& path, const cv::Scalar& colour, int width_px) {
  std::vector<cv::Point> points;
  for (const io::StampedPose& pose : path) {
    bool in_front = false;
    const cv::Point p = projectToImage(camera, T_c_w, pose.T_w_x.translation(), &in_front);
    if (!in_front) {
      if (points.size() > 1) cv::polylines(*image, points, false, colour, width_px, cv::LINE_AA, 2);
      points.clear();
      continue;
    }
    points.push_back(p);
  }
  if (points.size() > 1) cv::polylines(*image, points, false, colour, width_px, cv::LINE_AA, 2);
  if (!path.empty()) {
    bool in_front = false;
    const cv::Point start =
        projectToImage(camera, T_c_w, path.front().T_w_x.translation(), &in_front);
    if (in_front) cv::circle(*image, start, 4 * 5, colour, 2, cv::LINE_AA, 2);
  }
}

std::vector<std::size_t> pathViewIndices(const io::Trajectory& trajectory) {
  std::vector<std::size_t> indices;
  if (trajectory.empty()) return indices;
  for (int k = 1; k <= 3; ++k) indices.push_back((trajectory.size() - 1) * k / 4);
  return indices;
}

// Distance along `direction` from `centre` at which the model's bounding box fills 92 % of the
// picture (a few fixed-point steps: the projected size is not linear in the distance).
double fittingDistance(const DisplayFrame& frame, const PinholeCamera& camera, const Vec3& centre,
                       const Vec3& direction, const Vec3& up) {
  double distance = (frame.hi_d - frame.lo_d).norm();
  for (int iteration = 0; iteration < 6; ++iteration) {
    const SE3 T_c_w = lookAt(centre + distance * direction, centre, up);
    double fill = 0.0;
    for (int corner = 0; corner < 8; ++corner) {
      const Vec3 p_d((corner & 1) ? frame.hi_d.x() : frame.lo_d.x(),
                     (corner & 2) ? frame.hi_d.y() : frame.lo_d.y(),
                     (corner & 4) ? frame.hi_d.z() : frame.lo_d.z());
      const Vec3 p_c = T_c_w * frame.toWorld(p_d);
      if (p_c.z() < 0.1) {
        fill = 2.0;  // a corner behind the camera: step back
        break;
      }
      fill = std::max(fill, std::abs(p_c.x() / p_c.z()) * camera.fx() / (0.5 * camera.width()));
      fill = std::max(fill, std::abs(p_c.y() / p_c.z()) * camera.fy() / (0.5 * camera.height()));
    }
    distance *= 0.5 + 0.5 * fill / 0.92;
  }
  return distance;
}

std::vector<View> makeViews(const DisplayFrame& frame, const io::Trajectory& trajectory,
                            const SnapshotOptions& options) {
  std::vector<View> views;
  const Vec3 extent = frame.hi_d - frame.lo_d;
  const Vec3 up = frame.axis(2);

  {  // Bird's eye: the floor's bounds fill the picture.
    View v;
    v.name = "bird_eye";
    v.label = "bird's eye";
    v.camera = viewCamera(options.width, options.height, kBirdEyeFovDeg);
    const double tan_h = 0.5 * options.width / v.camera.fx();
    const double tan_v = 0.5 * options.height / v.camera.fy();
    const double distance = 1.08 * std::max(0.5 * extent.x() / tan_h, 0.5 * extent.y() / tan_v);
    const Vec3 floor_centre_d(0.5 * (frame.lo_d.x() + frame.hi_d.x()),
                              0.5 * (frame.lo_d.y() + frame.hi_d.y()), frame.lo_d.z());
    const Vec3 target = frame.toWorld(floor_centre_d);
    v.T_c_w = lookAt(target + distance * up, target, frame.axis(1));
    v.far_m = distance + extent.norm() + 1.0;
    views.push_back(v);
  }
  const std::vector<std::size_t> path_indices = pathViewIndices(trajectory);
  for (std::size_t k = 0; k < path_indices.size(); ++k) {
    const SE3& T_w_c = trajectory[path_indices[k]].T_w_x;
    const Vec3 forward = T_w_c.rotationMatrix().col(2);
    Vec3 horizontal = forward - up * up.dot(forward);
    horizontal = horizontal.norm() > 1e-6 ? horizontal.normalized() : frame.axis(0);
    const Vec3 eye = T_w_c.translation() - 0.5 * horizontal + 0.25 * up;
    View v;
    v.name = "path_" + std::to_string(k + 1);
    v.label = "path " + std::to_string(k + 1) + " (t = " +
              cv::format("%.1f", trajectory[path_indices[k]].t_s - trajectory.front().t_s) + " s)";
    v.camera = viewCamera(options.width, options.height, options.fov_deg);
    v.T_c_w = lookAt(eye, T_w_c.translation() + 2.0 * forward, up);
    v.far_m = 2.0 * extent.norm() + 1.0;
    views.push_back(v);
  }
  {  // Orbit around the model's centre, each view as close as the bounding box allows.
    const PinholeCamera camera = viewCamera(options.width, options.height, options.fov_deg);
    const double radius = 0.5 * extent.norm();
    const Vec3 centre = frame.toWorld(0.5 * (frame.lo_d + frame.hi_d));
    const double elevation = kOrbitElevationDeg * M_PI / 180.0;
    for (int k = 0; k < 8; ++k) {
      const double azimuth = k * M_PI / 4.0;
      const Vec3 direction = std::cos(elevation) * (std::cos(azimuth) * frame.axis(0) +
                                                    std::sin(azimuth) * frame.axis(1)) +
                             std::sin(elevation) * up;
      const double distance = fittingDistance(frame, camera, centre, direction, up);
      View v;
      v.name = "orbit_" + std::to_string(k);
      v.label = "orbit " + std::to_string(k * 45) + " deg";
      v.camera = camera;
      v.T_c_w = lookAt(centre + distance * direction, centre, up);
      v.far_m = distance + 2.0 * radius + 1.0;
      views.push_back(v);
    }
  }
  if (options.user_view) {
    View v;
    v.name = "user_view";
    v.label = "user view";
    v.camera = viewCamera(options.width, options.height, options.fov_deg);
    const Vec3 direction = options.user_view->target_w - options.user_view->eye_w;
    // Up in the image: the world's up unless looking (almost) straight along it.
    const Vec3 image_up = direction.normalized().cross(up).norm() > 0.05 ? up : frame.axis(1);
    v.T_c_w = lookAt(options.user_view->eye_w, options.user_view->target_w, image_up);
    v.far_m = direction.norm() + 2.0 * extent.norm() + 1.0;
    views.push_back(v);
  }
  return views;
}

void writePng(const std::string& path, const cv::Mat& image) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, image);
  } catch (const cv::Exception& e) {
    throw InputError(path, 0, "cannot write image (" + e.msg + ")");
  }
  if (!ok) throw InputError(path, 0, "cannot write image");
}

}  // namespace

Vec3 estimateUpDirection(const io::Trajectory& trajectory) {
  if (trajectory.size() < 3) return Vec3::UnitZ();
  Vec3 camera_up = Vec3::Zero();  // image up (-y of the camera) in the world
  Vec3 mean = Vec3::Zero();
  for (const io::StampedPose& pose : trajectory) {
    camera_up -= pose.T_w_x.rotationMatrix().col(1);
    mean += pose.T_w_x.translation();
  }
  mean /= static_cast<double>(trajectory.size());
  camera_up.normalize();
  Mat3 cov = Mat3::Zero();
  for (const io::StampedPose& pose : trajectory) {
    const Vec3 d = pose.T_w_x.translation() - mean;
    cov += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Mat3> eig(cov);
  const Vec3 values = eig.eigenvalues();  // ascending
  Vec3 normal = eig.eigenvectors().col(0);
  // Planar motion (a ground robot): the plane's normal, if the cameras are roughly upright on it.
  if (values[1] > 0.01 && values[0] < 0.05 * values[1] && std::abs(normal.dot(camera_up)) > 0.7) {
    return normal.dot(camera_up) > 0 ? normal : Vec3(-normal);
  }
  return camera_up;
}

PinholeCamera viewCamera(int width, int height, double fov_deg) {
  const double f = 0.5 * width / std::tan(0.5 * fov_deg * M_PI / 180.0);
  return PinholeCamera(f, f, 0.5 * (width - 1), 0.5 * (height - 1), width, height);
}

std::vector<std::string> writeSnapshots(const SnapshotScene& scene, const SnapshotOptions& options,
                                        const std::string& dir) {
  LTLO_ASSERT(scene.surfels != nullptr, "writeSnapshots: no surfels");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError(dir, 0, "cannot create folder (" + ec.message() + ")");
  const std::vector<Surfel>& surfels = *scene.surfels;
  const DisplayFrame frame = displayFrame(surfels, scene.estimate);
  const std::vector<View> views = makeViews(frame, scene.estimate, options);

  render::OffscreenRenderer renderer(options.width, options.height);
  render::SplatSet splats;
  splats.positions_o.reserve(surfels.size());
  splats.normals_o.reserve(surfels.size());
  splats.radii_m.reserve(surfels.size());
  splats.colours_rgb.reserve(surfels.size());
  for (const Surfel& s : surfels) {
    splats.positions_o.push_back(s.position_w);
    splats.normals_o.push_back(s.normal_w);
    splats.radii_m.push_back(kDisplayRadiusScale * s.radius_m);
    splats.colours_rgb.push_back(s.colour_rgb / 255.0f);
  }
  splats.ambient = kAmbient;
  splats.cull_back_facing = true;
  const int model = renderer.addSplats(std::move(splats));

  std::vector<std::string> paths;
  std::vector<Tile> tiles;
  for (const View& view : views) {
    render::RenderView rv;
    rv.camera = view.camera;
    rv.T_c_w = view.T_c_w;
    rv.near_m = 0.05;
    rv.far_m = view.far_m;
    rv.background_rgb = kBackground;
    cv::Mat image = renderer.render(rv, {render::DrawItem{model, SE3()}}).bgr;
    if (view.name == "bird_eye") {
      if (!scene.ground_truth.empty()) {
        drawPath(&image, view.camera, view.T_c_w, scene.ground_truth, kGroundTruthBgr, 5);
      }
      drawPath(&image, view.camera, view.T_c_w, scene.estimate, kEstimateBgr, 2);
      const std::vector<std::size_t> marks = pathViewIndices(scene.estimate);
      for (std::size_t k = 0; k < marks.size(); ++k) {
        bool in_front = false;
        const cv::Point p = projectToImage(view.camera, view.T_c_w,
                                           scene.estimate[marks[k]].T_w_x.translation(), &in_front);
        if (!in_front) continue;
        const cv::Point centre(p.x / 4, p.y / 4);
        cv::circle(image, centre, 10, cv::Scalar(255, 255, 255), cv::FILLED, cv::LINE_AA);
        cv::putText(image, std::to_string(k + 1), centre + cv::Point(-5, 6),
                    cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
      }
      std::vector<std::pair<std::string, cv::Scalar>> legend = {
          {scene.estimate_label, kEstimateBgr}};
      if (!scene.ground_truth.empty()) legend.push_back({"ground truth", kGroundTruthBgr});
      drawLegend(&image, legend);
    }
    drawLabel(&image, view.label + cv::format(" | %zu surfels", surfels.size()));
    const std::string path = dir + "/" + view.name + ".png";
    writePng(path, image);
    paths.push_back(path);
    tiles.push_back({view.label, image});
  }

  if (!scene.overlays.empty()) {
    std::vector<cv::Mat> rows;
    for (const OverlayFrame& f : scene.overlays) {
      cv::Mat row = overlayRow(f);
      rows.push_back(row);
      tiles.push_back({cv::format("frame %d", f.index), row});
    }
    cv::Mat sheet;
    cv::vconcat(rows, sheet);
    const std::string path = dir + "/frames.png";
    writePng(path, sheet);
    paths.push_back(path);
  }

  const std::string sheet_path = dir + "/contact_sheet.png";
  writePng(sheet_path, contactSheet(tiles, scene.title, /*columns=*/4, /*tile_width=*/320));
  paths.push_back(sheet_path);
  return paths;
}

}  // namespace ltlo::recon
