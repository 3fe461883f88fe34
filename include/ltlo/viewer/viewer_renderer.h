#pragma once
/// The live viewer's picture (issue 30): two panels side by side, each Viewer.PanelWidth x
/// Viewer.PanelHeight.
///   left   the current colour frame, dynamic pixels tinted red, keypoints coloured by use
///          (kTrackedColour / kUntrackedColour / kDynamicColour), a status line on top (time,
///          frame, tracking state, map, keyframes, loops, merges, FPS, dynamic share);
///   right  the map seen from a camera that follows the current one (Viewer.FollowDistance
///          behind, Viewer.FollowHeight above, along its own axes): map points coloured by beta
///          (red = dynamic 0 ... green = static 1), keyframes as blue frusta, covisibility edges,
///          loop edges (magenta; yellow and thicker for Viewer.LoopFlashSeconds after a loop or
///          merge, while the view pulls back to the whole map: Viewer.LoopOverview), the
///          trajectory so far (orange) and the current camera (a larger frustum, white when
///          tracked, red when not).
/// Rendered headless with OSMesa (render/offscreen_renderer.h). Not thread-safe: one renderer per
/// thread (the viewer's); its OSMesa context is created by the constructor's thread and made
/// current on every render().
#include <memory>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "ltlo/core/settings.h"
#include "ltlo/viewer/viewer_state.h"

namespace ltlo::render {
class OffscreenRenderer;
}

namespace ltlo::viewer {

/// Labels of the 3-D panel's items (ViewerPicture::labels_3d): which item each pixel shows.
enum ViewerLabel : std::uint8_t {
  kLabelBackground = 0,
  kLabelStaticPoint = 1,   ///< map point with beta >= 0.5
  kLabelDynamicPoint = 2,  ///< map point with beta < 0.5
  kLabelKeyFrame = 3,
  kLabelCovisibility = 4,
  kLabelLoopEdge = 5,
  kLabelTrajectory = 6,
  kLabelCurrentCamera = 7,
};

/// Keypoint colours of the left panel (BGR).
inline const cv::Scalar kTrackedColour(0, 255, 0);
inline const cv::Scalar kUntrackedColour(255, 160, 0);
inline const cv::Scalar kDynamicColour(0, 0, 255);

struct ViewerPicture {
  cv::Mat bgr;        ///< CV_8UC3, 2 PanelWidth x PanelHeight
  cv::Mat labels_3d;  ///< CV_8U, the right panel's ViewerLabel per pixel (PanelWidth x PanelHeight)
};

class ViewerRenderer {
 public:
  explicit ViewerRenderer(const ViewerOptions& options);
  ~ViewerRenderer();
  ViewerRenderer(const ViewerRenderer&) = delete;
  ViewerRenderer& operator=(const ViewerRenderer&) = delete;

  ViewerPicture render(const ViewerState& state);

  int width() const { return 2 * options_.panel_width; }
  int height() const { return options_.panel_height; }

 private:
  void drawFramePanel(const ViewerState& state, cv::Mat& panel) const;
  void drawMapPanel(const ViewerState& state, cv::Mat& panel, cv::Mat& labels);

  ViewerOptions options_;
  std::unique_ptr<render::OffscreenRenderer> renderer_;
  SE3 last_T_w_c_;  ///< the 3-D view keeps following the last pose while a frame has none
};

/// The 3-D panel's camera pose (camera-from-world) following a camera at T_w_c: behind it by
/// `distance_m` along its optical axis, above it by `height_m` along its -y (image up), looking
/// at a point 1 m in front of it with the same image-up direction.
SE3 followView_T_v_w(const SE3& T_w_c, double distance_m, double height_m);

/// Margin around the keyframe centres the overview keeps in view (frusta, points near them), m.
inline constexpr double kOverviewMargin_m = 0.5;

struct OverviewView {
  SE3 T_v_w;           ///< camera-from-world of the 3-D panel
  double far_m = 0.0;  ///< far plane that keeps the whole map
};

/// The 3-D panel's camera while a loop flashes (Viewer.LoopOverview): looking at the centre of the
/// box around the keyframes and the current camera, from the following camera's side (behind and
/// above T_w_c, as followView_T_v_w), far enough back that a sphere around all of them (plus
/// kOverviewMargin_m) fits the vertical half field of view `half_fov_rad`; never nearer than the
/// following camera.
OverviewView overviewView(const SE3& T_w_c, const std::vector<SE3>& keyframes_T_w_c, double distance_m,
                          double height_m, double half_fov_rad);

}  // namespace ltlo::viewer
