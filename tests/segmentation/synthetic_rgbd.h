#pragma once
// Ray-cast RGB-D frames of a small generated room for the dense-segmentation tests: a back wall, a
// left wall and a floor (static, world frame) and a box (dynamic, its own pose per frame). Every
// surface carries a smooth multi-frequency texture in its own frame, so the intensity is exact and
// differentiable; depth is exact (no noise, no holes). World: x right, y down, z forward (the first
// camera frame).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include <opencv2/core.hpp>

#include "ltlo/core/camera.h"
#include "ltlo/core/lie.h"

namespace ltlo::segmentation::test {

struct RgbdFrame {
  cv::Mat color_bgr;  // CV_8UC3
  cv::Mat depth_m;    // CV_32F
  cv::Mat dynamic;    // CV_8U, 255 on the box
};

struct BoxInWorld {
  SE3 T_w_o;                              // box frame: centre, axes along the box edges
  Vec3 half_size_m = Vec3(0.35, 0.4, 0.3);  // half extents along x, y, z of the box frame
};

/// Intensity in [0.1, 0.9]: smooth texture of a point in a surface's own 2-D coordinates.
inline double texture(double a, double b, double phase) {
  return 0.5 + 0.16 * std::sin(9.0 * a + phase) * std::cos(7.0 * b - 0.5 * phase) + 0.12 * std::sin(23.0 * a + 17.0 * b) +
         0.08 * std::cos(41.0 * b - 11.0 * a + phase);
}

/// `contrast` scales every surface's texture about mid-grey (1: as texture(); below 1: the
/// weakly textured walls of a real room).
inline RgbdFrame renderRoom(const PinholeCamera& camera, const SE3& T_w_c, const BoxInWorld& box,
                            double contrast = 1.0) {
  RgbdFrame frame;
  frame.color_bgr.create(camera.height(), camera.width(), CV_8UC3);
  frame.depth_m.create(camera.height(), camera.width(), CV_32F);
  frame.dynamic.create(camera.height(), camera.width(), CV_8U);
  const Mat3 R_w_c = T_w_c.rotationMatrix();
  const Vec3 o_w = T_w_c.translation();
  const SE3 T_o_w = box.T_w_o.inverse();
  for (int v = 0; v < camera.height(); ++v) {
    for (int u = 0; u < camera.width(); ++u) {
      const Vec3 ray_c((u - camera.cx()) / camera.fx(), (v - camera.cy()) / camera.fy(), 1.0);
      const Vec3 d_w = R_w_c * ray_c;
      double best_t = std::numeric_limits<double>::max();
      double intensity = 0.0;
      bool dynamic = false;
      auto plane = [&](int axis, double value, double phase) {  // world plane x/y/z = value
        if (std::abs(d_w(axis)) < 1e-9) return;
        const double t = (value - o_w(axis)) / d_w(axis);
        if (t <= 0.0 || t >= best_t) return;
        const Vec3 p = o_w + t * d_w;
        best_t = t;
        intensity = texture(p((axis + 1) % 3), p((axis + 2) % 3), phase);
        dynamic = false;
      };
      plane(2, 3.5, 0.0);   // back wall
      plane(0, -2.0, 1.0);  // left wall
      plane(1, 1.0, 2.0);   // floor, 1 m below the first camera
      // Box: slab intersection in the box frame.
      const Vec3 o_o = T_o_w * o_w;
      const Vec3 d_o = T_o_w.rotationMatrix() * d_w;
      double t_near = 0.0, t_far = std::numeric_limits<double>::max();
      int near_axis = -1;
      for (int axis = 0; axis < 3; ++axis) {
        if (std::abs(d_o(axis)) < 1e-12) {
          if (std::abs(o_o(axis)) > box.half_size_m(axis)) t_near = t_far + 1.0;
          continue;
        }
        double t0 = (-box.half_size_m(axis) - o_o(axis)) / d_o(axis);
        double t1 = (box.half_size_m(axis) - o_o(axis)) / d_o(axis);
        if (t0 > t1) std::swap(t0, t1);
        if (t0 > t_near) {
          t_near = t0;
          near_axis = axis;
        }
        t_far = std::min(t_far, t1);
      }
      if (near_axis >= 0 && t_near <= t_far && t_near > 0.0 && t_near < best_t) {
        best_t = t_near;
        const Vec3 p = o_o + t_near * d_o;
        intensity = texture(p((near_axis + 1) % 3) + 0.3, p((near_axis + 2) % 3), 3.0 + near_axis);
        dynamic = true;
      }
      const double z_m = best_t * ray_c.z();  // ray_c.z = 1: t is the depth along the optical axis
      frame.depth_m.at<float>(v, u) = best_t < 1e6 ? static_cast<float>(z_m) : 0.0f;
      if (contrast != 1.0) intensity = 0.5 + contrast * (intensity - 0.5);
      const auto grey = static_cast<std::uint8_t>(std::clamp(255.0 * intensity, 0.0, 255.0));
      frame.color_bgr.at<cv::Vec3b>(v, u) = cv::Vec3b(grey, grey, grey);
      frame.dynamic.at<std::uint8_t>(v, u) = dynamic ? 255 : 0;
    }
  }
  return frame;
}

}  // namespace ltlo::segmentation::test
