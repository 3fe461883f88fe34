#include "lens_render.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>

#include "ltlo/core/errors.h"

namespace ltlo::sim {
namespace {

// Second difference of 1/z (1/m) above which three canvas pixels do not lie on one plane. The 24-bit
// depth buffer resolves 1/z to ~1.2e-6 /m (near 0.05 m, far 30 m); a depth step of 1 % at 5 m is 2e-3.
constexpr float kPlanarTolerance = 1e-4f;
// Canvas margin beyond the undistorted positions: bilinear colour reads floor(x) + 1, the depth's
// slope the nearest pixel's neighbours.
constexpr int kMarginPx = 2;

}  // namespace

RawFrameRenderer::RawFrameRenderer(const CameraModel& model, double readout_s, int bands)
    : model_(model), lens_(model.isDistorted()) {
  const PinholeCamera& K = model.pinhole();
  const int width = K.width(), height = K.height();
  canvas_ = K;
  if (lens_) {
    map_x_.create(height, width, CV_32F);
    map_y_.create(height, width, CV_32F);
    double min_x = 1e30, max_x = -1e30, min_y = 1e30, max_y = -1e30;
    std::vector<Vec2> ideal(static_cast<size_t>(width) * height);
    for (int v = 0; v < height; ++v) {
      for (int u = 0; u < width; ++u) {
        const std::optional<Vec2> p = model.undistortPixel(Vec2(u, v));
        if (!p) {
          std::ostringstream text;
          text << "Sensor.Distortion: raw pixel (" << u << ", " << v << ") does not undistort ("
               << model.lens().describe() << "): not a lens over the whole " << width << "x" << height << " image";
          throw ConfigError(text.str());
        }
        ideal[static_cast<size_t>(v) * width + u] = *p;
        min_x = std::min(min_x, p->x());
        max_x = std::max(max_x, p->x());
        min_y = std::min(min_y, p->y());
        max_y = std::max(max_y, p->y());
      }
    }
    // Canvas column 0 is ideal column offset_x: the canvas is the ideal camera with cx moved by it.
    const int offset_x = static_cast<int>(std::floor(min_x)) - kMarginPx;
    const int offset_y = static_cast<int>(std::floor(min_y)) - kMarginPx;
    const int canvas_width = static_cast<int>(std::ceil(max_x)) + kMarginPx - offset_x + 1;
    const int canvas_height = static_cast<int>(std::ceil(max_y)) + kMarginPx - offset_y + 1;
    canvas_ = PinholeCamera(K.fx(), K.fy(), K.cx() - offset_x, K.cy() - offset_y, canvas_width, canvas_height);
    nearest_.create(height, width, CV_32SC2);
    for (int v = 0; v < height; ++v) {
      for (int u = 0; u < width; ++u) {
        const Vec2& p = ideal[static_cast<size_t>(v) * width + u];
        const float x = static_cast<float>(p.x() - offset_x), y = static_cast<float>(p.y() - offset_y);
        map_x_.at<float>(v, u) = x;
        map_y_.at<float>(v, u) = y;
        nearest_.at<cv::Vec2i>(v, u) = cv::Vec2i(static_cast<int>(std::floor(x + 0.5f)), static_cast<int>(std::floor(y + 0.5f)));
      }
    }
  }

  const int num_bands = readout_s > 0.0 ? std::clamp(bands, 1, height) : 1;
  for (int b = 0; b < num_bands; ++b) {
    Band band;
    band.raw_row0 = b * height / num_bands;
    band.raw_rows = (b + 1) * height / num_bands - band.raw_row0;
    const double centre_row = band.raw_row0 + 0.5 * (band.raw_rows - 1);
    band.dt_s = height > 1 ? (centre_row - 0.5 * (height - 1)) * readout_s / (height - 1) : 0.0;
    int canvas_rows = band.raw_rows;
    band.canvas_row0 = band.raw_row0;
    if (lens_) {
      double lo, hi;
      cv::minMaxLoc(map_y_.rowRange(band.raw_row0, band.raw_row0 + band.raw_rows), &lo, &hi);
      band.canvas_row0 = num_bands == 1 ? 0 : std::max(0, static_cast<int>(std::floor(lo)) - kMarginPx);
      canvas_rows = num_bands == 1 ? canvas_.height()
                                   : std::min(canvas_.height(), static_cast<int>(std::ceil(hi)) + kMarginPx + 1) -
                                         band.canvas_row0;
    }
    buffer_rows_ = std::max(buffer_rows_, canvas_rows);
    bands_.push_back(band);
  }
}

render::RenderResult RawFrameRenderer::render(render::OffscreenRenderer& gl, double t_s, const ViewAt& view_at,
                                              double near_m, double far_m) const {
  const PinholeCamera& K = model_.pinhole();
  render::RenderResult raw;
  raw.bgr.create(K.height(), K.width(), CV_8UC3);
  raw.depth_m.create(K.height(), K.width(), CV_32F);
  raw.labels.create(K.height(), K.width(), CV_8U);
  for (const Band& band : bands_) {
    // The band's canvas rows as a camera of their own: moving the principal point up crops the view.
    const PinholeCamera crop(canvas_.fx(), canvas_.fy(), canvas_.cx(), canvas_.cy() - band.canvas_row0,
                             canvas_.width(), buffer_rows_);
    const View view = view_at(t_s + band.dt_s);
    const render::RenderResult canvas = gl.render({crop, view.T_c_w, near_m, far_m}, view.items);
    sampleBand(band, canvas, &raw);
  }
  return raw;
}

void RawFrameRenderer::sampleBand(const Band& band, const render::RenderResult& canvas,
                                  render::RenderResult* raw) const {
  const cv::Range rows(band.raw_row0, band.raw_row0 + band.raw_rows);
  if (!lens_) {  // rolling shutter alone: the band's rows are the crop's first rows
    const cv::Range crop_rows(0, band.raw_rows);
    canvas.bgr.rowRange(crop_rows).copyTo(raw->bgr.rowRange(rows));
    canvas.depth_m.rowRange(crop_rows).copyTo(raw->depth_m.rowRange(rows));
    canvas.labels.rowRange(crop_rows).copyTo(raw->labels.rowRange(rows));
    return;
  }
  const float row0 = static_cast<float>(band.canvas_row0);
  cv::Mat map_y = map_y_.rowRange(rows) - row0;
  cv::Mat bgr_rows = raw->bgr.rowRange(rows);
  cv::remap(canvas.bgr, bgr_rows, map_x_.rowRange(rows), map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);

  const int canvas_w = canvas.depth_m.cols, canvas_h = canvas.depth_m.rows;
  for (int v = rows.start; v < rows.end; ++v) {
    const cv::Vec2i* nearest = nearest_.ptr<cv::Vec2i>(v);
    const float* mx = map_x_.ptr<float>(v);
    const float* my = map_y_.ptr<float>(v);
    float* depth = raw->depth_m.ptr<float>(v);
    uint8_t* label = raw->labels.ptr<uint8_t>(v);
    for (int u = 0; u < raw->depth_m.cols; ++u) {
      const int x = nearest[u][0], y = nearest[u][1] - band.canvas_row0;
      const uint8_t l = canvas.labels.at<uint8_t>(y, x);
      const float z = canvas.depth_m.at<float>(y, x);
      label[u] = l;
      if (z <= 0.0f) {
        depth[u] = 0.0f;
        continue;
      }
      // Slope of 1/z along one axis towards the sample (offset d): from the two pixels on the sample's
      // side when the three lie on one plane (a crease or an edge beyond the nearest pixel leaves it
      // intact), else from both neighbours when those three do; else none (an edge: nearest).
      const float w = 1.0f / z;
      auto inverseDepth = [&](int xi, int yi, float* wi) {
        if (xi < 0 || yi < 0 || xi >= canvas_w || yi >= canvas_h) return false;
        const float zi = canvas.depth_m.at<float>(yi, xi);
        if (zi <= 0.0f || canvas.labels.at<uint8_t>(yi, xi) != l) return false;
        *wi = 1.0f / zi;
        return true;
      };
      auto slope = [&](int dx, int dy, float d) {
        const int s = d < 0.0f ? -1 : 1;
        float w1, w2, wa, wb;
        if (inverseDepth(x + s * dx, y + s * dy, &w1) && inverseDepth(x + 2 * s * dx, y + 2 * s * dy, &w2) &&
            std::abs(w2 - 2.0f * w1 + w) < kPlanarTolerance)
          return s * (w1 - w);
        if (inverseDepth(x - dx, y - dy, &wa) && inverseDepth(x + dx, y + dy, &wb) &&
            std::abs(wa + wb - 2.0f * w) < kPlanarTolerance)
          return 0.5f * (wb - wa);
        return 0.0f;
      };
      const float d_x = mx[u] - static_cast<float>(x), d_y = my[u] - row0 - static_cast<float>(y);
      const float w_sample = w + slope(1, 0, d_x) * d_x + slope(0, 1, d_y) * d_y;
      depth[u] = w_sample > 0.0f ? 1.0f / w_sample : z;
    }
  }
}

}  // namespace ltlo::sim
