#pragma once
// Generated RGB-D pairs for the dense-solver tests (dense_solver_test.cc, dense_brightness_test.cc):
// the room of synthetic_rgbd.h seen from a camera on a moving body, with a textured box covering
// about 70 % of the view that moves with the body (the pushed / carried box of the LTLO scenarios),
// or with the box out of sight. Helpers prepare the dense frames and clusters, build IMU priors and
// measure the static IoU of a segmentation.
#include <cmath>
#include <functional>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "ltlo/imu/preintegration.h"
#include "ltlo/segmentation/dense_frame.h"
#include "ltlo/segmentation/dense_solver.h"
#include "ltlo/segmentation/depth_kmeans.h"
#include "segmentation/synthetic_rgbd.h"

namespace ltlo::segmentation::test {

constexpr double kDt = 1.0 / 30.0;

struct Prepared {
  DenseFrame dense;
  DepthClusters clusters;
  cv::Mat dynamic;  // ground truth at the input resolution
};

/// A box 0.8 m in front of the first camera, 0.7 x 0.9 m, rigidly attached to the body.
struct Scene {
  PinholeCamera camera = PinholeCamera(525.0, 525.0, 319.5, 239.5, 640, 480);
  /// camera in the body frame: rotated and offset, as on a robot
  SE3 T_b_c = SE3(so3ExpQuat(Vec3(0.04, -0.08, 0.02)), Vec3(0.05, -0.02, 0.10));
  SE3 T_b_o;  // the box in the body frame
  /// body motion over one frame: constant world velocity and body angular rate
  Vec3 v_w_b = Vec3(0.25, 0.02, 0.85);
  Vec3 omega_b = Vec3(0.03, 0.45, -0.05);
  /// false: the box stays 50 m behind the first camera (the static room alone)
  bool with_box = true;
  /// true: the box moves through the world at box_velocity_w from where it is at t = 0 instead of
  /// with the body (a mover that keeps its own pace)
  bool box_in_world = false;
  Vec3 box_velocity_w = Vec3::Zero();
  /// true: depth noise of a structured-light sensor, sigma(z) = 1.2 mm + 1.9 mm (z - 0.4 m)^2 per
  /// pixel (Nguyen et al. 2012's Kinect model), the same at every call for the same t_s
  bool depth_noise = false;
  /// texture contrast of every surface (renderRoom)
  double contrast = 1.0;

  Scene() {
    const SE3 T_c_o(Quat::Identity(), Vec3(0.05, 0.15, 1.1));
    T_b_o = T_b_c * T_c_o;
  }
  /// Body pose at time t (the first camera at the world origin at t = 0).
  SE3 T_w_b(double t_s) const {
    const SE3 T_w_b0 = T_b_c.inverse();
    return SE3(Quat(T_w_b0.rotationMatrix() * so3Exp(omega_b * t_s)), T_w_b0.translation() + v_w_b * t_s);
  }
  RgbdFrame render(double t_s) const {
    BoxInWorld box;
    box.T_w_o = with_box ? T_w_b(t_s) * T_b_o : SE3(Quat::Identity(), Vec3(0.0, 0.0, -50.0));
    if (with_box && box_in_world) box.T_w_o = SE3(Quat::Identity(), box_velocity_w * t_s) * T_w_b(0.0) * T_b_o;
    box.half_size_m = Vec3(0.35, 0.45, 0.3);
    RgbdFrame frame = renderRoom(camera, T_w_b(t_s) * T_b_c, box, contrast);
    if (depth_noise) {
      cv::RNG rng(static_cast<std::uint64_t>(std::llround((t_s + 10.0) * 1e6)));
      for (int r = 0; r < frame.depth_m.rows; ++r) {
        float* z = frame.depth_m.ptr<float>(r);
        for (int c = 0; c < frame.depth_m.cols; ++c) {
          if (!(z[c] > 0.0f)) continue;
          const double d = z[c] - 0.4;
          z[c] += static_cast<float>(rng.gaussian(0.0012 + 0.0019 * d * d));
        }
      }
    }
    return frame;
  }
};

inline DenseOptions denseOptions() {
  DenseOptions dense;  // DESIGN.md defaults: 320x240, 3 levels
  dense.finest_level = 1;
  return dense;
}

inline SegmentationOptions segmentationOptions() { return SegmentationOptions(); }

/// Renders the scene at t_s, lets `edit` change the colour image (e.g. an exposure step; may be
/// empty), then builds the dense frame and its clusters.
inline void prepare(const Scene& scene, double t_s, DepthKMeans& kmeans, Prepared* out,
                    const SegmentationOptions& segmentation = segmentationOptions(),
                    const std::function<void(cv::Mat&)>& edit = {}) {
  RgbdFrame frame = scene.render(t_s);
  if (edit) edit(frame.color_bgr);
  out->dense.build(frame.color_bgr, frame.depth_m, scene.camera, DenseFrameOptions::from(segmentation, denseOptions()));
  const DenseLevel& base = out->dense.level(0);
  kmeans.cluster(base.depth_m,
                 PinholeCamera(base.camera.fx, base.camera.fy, base.camera.cx, base.camera.cy, base.camera.width,
                               base.camera.height),
                 &out->clusters);
  out->dense.setLabels(out->clusters.labels, out->clusters.num_clusters);
  out->dynamic = frame.dynamic;
}

/// Static-background IoU of the segmentation (labels + gamma, threshold 0.5) against the truth.
inline double staticIou(const Prepared& frame, const std::vector<double>& gamma) {
  cv::Mat truth;
  cv::resize(frame.dynamic, truth, frame.clusters.labels.size(), 0.0, 0.0, cv::INTER_NEAREST);
  int intersection = 0, union_count = 0;
  for (int r = 0; r < truth.rows; ++r) {
    for (int c = 0; c < truth.cols; ++c) {
      const bool est_static = gamma[frame.clusters.labels.at<std::uint8_t>(r, c)] >= 0.5;
      const bool true_static = truth.at<std::uint8_t>(r, c) == 0;
      intersection += est_static && true_static;
      union_count += est_static || true_static;
    }
  }
  return static_cast<double>(intersection) / union_count;
}

/// The world's y axis points down.
inline Vec3 gravityW() { return Vec3(0.0, 9.81, 0.0); }

/// The preintegration of the scene's true motion over one frame.
inline imu::Preintegrated truePreintegration(const Scene& scene) {
  imu::Preintegrated pim(imu::ImuBias{}, imu::ImuNoise{});
  constexpr int kSteps = 40;
  for (int k = 0; k < kSteps; ++k) {
    const double t_mid = (k + 0.5) * kDt / kSteps;
    const Vec3 specific_force_b = scene.T_w_b(t_mid).rotationMatrix().transpose() * (Vec3::Zero() - gravityW());
    pim.integrateStep(scene.omega_b, specific_force_b, kDt / kSteps);
  }
  return pim;
}

/// The IMU prior with the previous velocity off by velocity_error (uncertain by 0.2 m/s) and the
/// prediction from that wrong previous state: what the tracker would hand over.
inline DensePrior imuPrior(const Scene& scene, const imu::Preintegrated& pim, const Vec3& velocity_error) {
  DensePrior prior;
  prior.kind = DensePrior::Kind::kImu;
  prior.T_b_c = scene.T_b_c;
  prior.T_w_b_prev = scene.T_w_b(0.0);
  prior.v_w_b_prev = scene.v_w_b + velocity_error;
  prior.g_w = gravityW();
  prior.pim = &pim;
  prior.prev_velocity_sigma_m_s = 0.2;
  prior.T_w_b_pred = SE3(Quat(prior.T_w_b_prev.rotationMatrix() * pim.deltaR()),
                         prior.T_w_b_prev.translation() + prior.v_w_b_prev * kDt + 0.5 * gravityW() * kDt * kDt +
                             prior.T_w_b_prev.rotationMatrix() * pim.deltaP());
  prior.v_w_b_pred = prior.v_w_b_prev;
  return prior;
}

}  // namespace ltlo::segmentation::test
