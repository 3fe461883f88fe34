#include "ltlo/viewer/viewer_renderer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include <opencv2/imgproc.hpp>

#include "ltlo/core/camera.h"
#include "ltlo/render/look_at.h"
#include "ltlo/render/offscreen_renderer.h"

namespace ltlo::viewer {
namespace {

const Eigen::Vector3f kStaticRgb(0.25f, 0.85f, 0.35f);
const Eigen::Vector3f kDynamicRgb(0.95f, 0.15f, 0.1f);
const Eigen::Vector3f kKeyFrameRgb(0.3f, 0.5f, 1.0f);
const Eigen::Vector3f kCovisibilityRgb(0.35f, 0.45f, 0.35f);
const Eigen::Vector3f kLoopRgb(1.0f, 0.2f, 1.0f);
const Eigen::Vector3f kLoopFlashRgb(1.0f, 1.0f, 0.1f);
const Eigen::Vector3f kTrajectoryRgb(1.0f, 0.55f, 0.1f);
const Eigen::Vector3f kTrackedCameraRgb(1.0f, 1.0f, 1.0f);
const Eigen::Vector3f kLostCameraRgb(1.0f, 0.1f, 0.1f);
const Eigen::Vector3f kBackgroundRgb(0.12f, 0.12f, 0.14f);

/// The virtual camera of the 3-D panel: about 80 degrees across.
PinholeCamera panelCamera(int width, int height) {
  const double f = 0.6 * width;
  return PinholeCamera(f, f, 0.5 * (width - 1), 0.5 * (height - 1), width, height);
}

/// The 8 segments of a camera frustum (centre to the four corners of an image plane at `depth_m`,
/// and that rectangle), for a 4:3 image, in the world.
void appendFrustum(const SE3& T_w_c, float depth_m, const Eigen::Vector3f& rgb, render::LineSet& lines) {
  const float half_w = 0.5f * depth_m;
  const float half_h = 0.375f * depth_m;
  const Eigen::Vector3f centre = T_w_c.translation().cast<float>();
  Eigen::Vector3f corners[4];
  const float signs[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  for (int k = 0; k < 4; ++k) {
    corners[k] = (T_w_c * Vec3(signs[k][0] * half_w, signs[k][1] * half_h, depth_m)).cast<float>();
  }
  for (int k = 0; k < 4; ++k) {
    lines.positions_o.push_back(centre);
    lines.positions_o.push_back(corners[k]);
    lines.positions_o.push_back(corners[k]);
    lines.positions_o.push_back(corners[(k + 1) % 4]);
  }
  lines.colours_rgb.insert(lines.colours_rgb.end(), 16, rgb);
}

void appendSegment(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& rgb,
                   render::LineSet& lines) {
  lines.positions_o.push_back(a);
  lines.positions_o.push_back(b);
  lines.colours_rgb.push_back(rgb);
  lines.colours_rgb.push_back(rgb);
}

/// The status in two lines: the frame and its tracking, then the map and the rate.
std::pair<std::string, std::string> statusLines(const ViewerState& state) {
  const ViewerFrame& f = state.frame;
  char first[160], second[160];
  std::snprintf(first, sizeof(first), "t %.2f s  frame %d  %s%s  map %llu", f.t_s, f.index, f.state.c_str(),
                f.imu_carried ? " (IMU only)" : "", static_cast<unsigned long long>(f.map));
  if (state.replay) {
    std::snprintf(second, sizeof(second), "KF %d  maps %d  replay  dynamic %.0f%%", state.map.keyframes_all_maps,
                  state.map.maps, 100.0 * state.dynamic_share);
  } else {
    std::snprintf(second, sizeof(second), "KF %d  maps %d  loops %d  merges %d  %.1f FPS  dynamic %.0f%%",
                  state.map.keyframes_all_maps, state.map.maps, state.map.loops, state.map.merges, state.fps,
                  100.0 * state.dynamic_share);
  }
  return {first, second};
}

}  // namespace

SE3 followView_T_v_w(const SE3& T_w_c, double distance_m, double height_m) {
  const Mat3 R_w_c = T_w_c.rotationMatrix();
  const Vec3 centre = T_w_c.translation();
  const Vec3 up_w = -R_w_c.col(1);  // image up
  const Vec3 eye = centre - distance_m * R_w_c.col(2) + height_m * up_w;
  return render::lookAt(eye, centre + R_w_c.col(2), up_w);
}

OverviewView overviewView(const SE3& T_w_c, const std::vector<SE3>& keyframes_T_w_c, double distance_m,
                          double height_m, double half_fov_rad) {
  const Mat3 R_w_c = T_w_c.rotationMatrix();
  const Vec3 up_w = -R_w_c.col(1);
  // The centre of the box around the keyframes and the current camera, and the radius around it.
  Vec3 low = T_w_c.translation(), high = T_w_c.translation();
  for (const SE3& T : keyframes_T_w_c) {
    low = low.cwiseMin(T.translation());
    high = high.cwiseMax(T.translation());
  }
  const Vec3 centre = 0.5 * (low + high);
  double radius_m = (T_w_c.translation() - centre).norm();
  for (const SE3& T : keyframes_T_w_c) radius_m = std::max(radius_m, (T.translation() - centre).norm());
  radius_m += kOverviewMargin_m;
  // From the same side as the following camera (behind and above the current one), back far
  // enough that a sphere of that radius fits the narrower field of view.
  Vec3 back = -distance_m * R_w_c.col(2) + height_m * up_w;
  back = back.norm() < 1e-9 ? Vec3(-R_w_c.col(2)) : Vec3(back.normalized());
  const double eye_distance_m =
      std::max(std::hypot(distance_m, height_m), radius_m / std::sin(std::clamp(half_fov_rad, 0.05, 1.5)));
  OverviewView view;
  view.T_v_w = render::lookAt(centre + eye_distance_m * back, centre, up_w);
  view.far_m = eye_distance_m + radius_m + 1.0;
  return view;
}

ViewerRenderer::ViewerRenderer(const ViewerOptions& options)
    : options_(options),
      renderer_(std::make_unique<render::OffscreenRenderer>(options.panel_width, options.panel_height)) {}

ViewerRenderer::~ViewerRenderer() = default;

ViewerPicture ViewerRenderer::render(const ViewerState& state) {
  ViewerPicture picture;
  picture.bgr.create(options_.panel_height, 2 * options_.panel_width, CV_8UC3);
  cv::Mat left = picture.bgr(cv::Rect(0, 0, options_.panel_width, options_.panel_height));
  cv::Mat right = picture.bgr(cv::Rect(options_.panel_width, 0, options_.panel_width, options_.panel_height));
  drawFramePanel(state, left);
  drawMapPanel(state, right, picture.labels_3d);
  return picture;
}

void ViewerRenderer::drawFramePanel(const ViewerState& state, cv::Mat& panel) const {
  const ViewerFrame& frame = state.frame;
  if (frame.color_bgr.empty()) {
    panel.setTo(cv::Scalar(0, 0, 0));
  } else {
    cv::resize(frame.color_bgr, panel, panel.size(), 0.0, 0.0, cv::INTER_AREA);
  }
  if (!frame.dynamic_mask.empty()) {
    cv::Mat mask;
    cv::resize(frame.dynamic_mask, mask, panel.size(), 0.0, 0.0, cv::INTER_NEAREST);
    // Dynamic pixels: halfway to red.
    for (int v = 0; v < panel.rows; ++v) {
      const std::uint8_t* m = mask.ptr<std::uint8_t>(v);
      cv::Vec3b* p = panel.ptr<cv::Vec3b>(v);
      for (int u = 0; u < panel.cols; ++u) {
        if (m[u] == 0) continue;
        p[u][0] = static_cast<std::uint8_t>(p[u][0] / 2);
        p[u][1] = static_cast<std::uint8_t>(p[u][1] / 2);
        p[u][2] = static_cast<std::uint8_t>(p[u][2] / 2 + 128);
      }
    }
  }
  if (!frame.color_bgr.empty()) {
    const double sx = static_cast<double>(panel.cols) / frame.color_bgr.cols;
    const double sy = static_cast<double>(panel.rows) / frame.color_bgr.rows;
    for (const ViewerKeypoint& kp : frame.keypoints) {
      const cv::Scalar& colour = kp.kind == KeypointClass::kTracked   ? kTrackedColour
                                 : kp.kind == KeypointClass::kDynamic ? kDynamicColour
                                                                      : kUntrackedColour;
      const cv::Point centre(static_cast<int>(std::lround(kp.u * sx)), static_cast<int>(std::lround(kp.v * sy)));
      cv::rectangle(panel, centre - cv::Point(1, 1), centre + cv::Point(1, 1), colour, cv::FILLED);
    }
  }
  // Two text lines on a black bar; the font scales with the panel (0.4 at 480 px wide).
  const double scale = 0.4 * panel.cols / 480.0;
  const int line_px = std::max(10, static_cast<int>(std::lround(18.0 * scale / 0.4)));
  panel(cv::Rect(0, 0, panel.cols, 2 * line_px + 4)).setTo(cv::Scalar(0, 0, 0));
  const auto [first, second] = statusLines(state);
  cv::putText(panel, first, cv::Point(4, line_px), cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(255, 255, 255), 1,
              cv::LINE_AA);
  cv::putText(panel, second, cv::Point(4, 2 * line_px), cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(255, 255, 255),
              1, cv::LINE_AA);
}

void ViewerRenderer::drawMapPanel(const ViewerState& state, cv::Mat& panel, cv::Mat& labels) {
  const ViewerMap& map = state.map;
  renderer_->clearDrawables();
  std::vector<render::DrawItem> items;

  render::PointSet static_points, dynamic_points;
  static_points.size_px = dynamic_points.size_px = static_cast<float>(options_.point_size_px);
  for (std::size_t i = 0; i < map.points_w.size(); ++i) {
    const float beta = std::clamp(i < map.beta.size() ? map.beta[i] : 1.0f, 0.0f, 1.0f);
    render::PointSet& set = beta >= 0.5f ? static_points : dynamic_points;
    set.positions_o.push_back(map.points_w[i]);
    set.colours_rgb.push_back(beta * kStaticRgb + (1.0f - beta) * kDynamicRgb);
  }
  auto add_points = [&](const render::PointSet& set, std::uint8_t label) {
    if (set.positions_o.empty()) return;
    render::DrawItem item;
    item.drawable = renderer_->addPoints(set);
    item.label = label;
    items.push_back(item);
  };
  add_points(static_points, kLabelStaticPoint);
  add_points(dynamic_points, kLabelDynamicPoint);

  auto add_lines = [&](const render::LineSet& set, std::uint8_t label) {
    if (set.positions_o.empty()) return;
    render::DrawItem item;
    item.drawable = renderer_->addLines(set);
    item.label = label;
    items.push_back(item);
  };
  render::LineSet covisibility;
  for (const auto& [a, b] : map.covisibility) {
    appendSegment(map.keyframes_T_w_c[a].translation().cast<float>(), map.keyframes_T_w_c[b].translation().cast<float>(),
                  kCovisibilityRgb, covisibility);
  }
  add_lines(covisibility, kLabelCovisibility);
  render::LineSet keyframes;
  keyframes.width_px = 1.0f;
  for (const SE3& T_w_c : map.keyframes_T_w_c) appendFrustum(T_w_c, 0.12f, kKeyFrameRgb, keyframes);
  add_lines(keyframes, kLabelKeyFrame);
  render::LineSet trajectory;
  trajectory.width_px = 2.0f;
  for (std::size_t i = 1; i < map.trajectory_w.size(); ++i) {
    appendSegment(map.trajectory_w[i - 1], map.trajectory_w[i], kTrajectoryRgb, trajectory);
  }
  add_lines(trajectory, kLabelTrajectory);
  render::LineSet loops;
  loops.width_px = state.flash_loop_edges ? 5.0f : 3.0f;
  for (const auto& [a, b] : map.loop_edges) {
    appendSegment(map.keyframes_T_w_c[a].translation().cast<float>(), map.keyframes_T_w_c[b].translation().cast<float>(),
                  state.flash_loop_edges ? kLoopFlashRgb : kLoopRgb, loops);
  }
  add_lines(loops, kLabelLoopEdge);

  const ViewerFrame& frame = state.frame;
  if (frame.has_pose) last_T_w_c_ = frame.T_w_c;
  render::LineSet camera;
  camera.width_px = 2.0f;
  if (frame.has_pose) {
    appendFrustum(frame.T_w_c, 0.3f, frame.tracked ? kTrackedCameraRgb : kLostCameraRgb, camera);
  }
  add_lines(camera, kLabelCurrentCamera);

  render::RenderView view;
  view.camera = panelCamera(options_.panel_width, options_.panel_height);
  view.T_c_w = followView_T_v_w(last_T_w_c_, options_.follow_distance_m, options_.follow_height_m);
  view.near_m = 0.05;
  view.far_m = 100.0;
  if (state.flash_loop_edges && options_.loop_overview && !map.loop_edges.empty()) {
    // The new edge may reach far behind the following camera: show the whole map while it flashes.
    const double half_fov_rad = std::atan(0.5 * options_.panel_height / view.camera.fx());
    const OverviewView overview = overviewView(last_T_w_c_, map.keyframes_T_w_c, options_.follow_distance_m,
                                               options_.follow_height_m, half_fov_rad);
    view.T_c_w = overview.T_v_w;
    view.near_m = 0.1;
    view.far_m = std::max(view.far_m, overview.far_m);
  }
  view.background_rgb = kBackgroundRgb;
  render::RenderResult result = renderer_->render(view, items);
  result.bgr.copyTo(panel);
  labels = result.labels;
}

}  // namespace ltlo::viewer
