#pragma once
/// Raw images of a camera with a lens and/or a rolling shutter, made from an ideal pinhole renderer.
///
/// Lens: the ideal pinhole of the same K is rendered on a canvas padded (or cropped) to cover every
/// raw pixel's undistorted position (CameraModel::undistortPixel), then each raw pixel samples the
/// canvas there: colour bilinearly (the lens blurs as it bends), labels at the nearest canvas pixel
/// (masks stay exact: one surface per pixel), and depth at the nearest canvas pixel corrected to
/// first order along that surface: 1/z is linear in the pixel coordinates on a plane, so where 1/z
/// is linear over three canvas pixels from the nearest one (same label, second difference at the
/// depth buffer's precision; the two towards the sample first, else both neighbours) its slope moves
/// the reading to the exact sample position, axis by axis; elsewhere (an edge) the nearest reading is
/// kept. Depth is never blended across an edge, and on planes it is the metric z of the surface seen
/// along the raw pixel's ray.
///
/// Rolling shutter: raw row v is exposed at t + (v - (H - 1) / 2) * readout / (H - 1). The raw rows
/// are split into bands; each band is rendered at its centre row's time (only the canvas rows it
/// samples: the principal point moves to crop) and its raw rows are composed from it.
#include <functional>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "ltlo/core/camera_model.h"
#include "ltlo/render/offscreen_renderer.h"

namespace ltlo::sim {

class RawFrameRenderer {
 public:
  /// What to draw at a given true time: the world-to-camera pose and the items.
  struct View {
    SE3 T_c_w;
    std::vector<render::DrawItem> items;
  };
  using ViewAt = std::function<View(double t_s)>;

  /// `model`: K and lens of the raw image; `readout_s` = 0 is a global shutter (then `bands` is
  /// ignored). Throws ConfigError when a raw pixel does not undistort (a lens folding over).
  RawFrameRenderer(const CameraModel& model, double readout_s, int bands);

  /// Size the OffscreenRenderer must have: the canvas, or the largest band of it.
  int bufferWidth() const { return canvas_.width(); }
  int bufferHeight() const { return buffer_rows_; }
  /// The padded ideal pinhole camera (K shifted by the padding).
  const PinholeCamera& canvas() const { return canvas_; }
  int numBands() const { return static_cast<int>(bands_.size()); }

  /// The raw image (bgr, depth_m, labels in the raw grid) whose centre row is exposed at t_s.
  render::RenderResult render(render::OffscreenRenderer& gl, double t_s, const ViewAt& view_at, double near_m,
                              double far_m) const;

 private:
  struct Band {
    int raw_row0 = 0, raw_rows = 0;  ///< raw rows [raw_row0, raw_row0 + raw_rows)
    int canvas_row0 = 0;             ///< first canvas row rendered for it
    double dt_s = 0.0;               ///< exposure time of its centre row relative to the frame's
  };
  void sampleBand(const Band& band, const render::RenderResult& canvas, render::RenderResult* raw) const;

  CameraModel model_;
  bool lens_ = false;
  PinholeCamera canvas_;
  cv::Mat map_x_, map_y_;  ///< CV_32F: canvas position of each raw pixel (lens only)
  cv::Mat nearest_;        ///< CV_32SC2: nearest canvas pixel (x, y) of each raw pixel
  std::vector<Band> bands_;
  int buffer_rows_ = 0;
};

}  // namespace ltlo::sim
