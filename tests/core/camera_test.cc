// Pinhole camera with depth (include/ltlo/core/camera.h): projection round trips and Jacobians
// against central differences.
#include "ltlo/core/camera.h"

#include <gtest/gtest.h>

#include "common/numeric_jacobian.h"
#include "ltlo/core/lie.h"

namespace ltlo {
namespace {

// TUM fr1-like VGA intrinsics with fx != fy so that swapped axes would show.
PinholeCamera vgaCamera() { return PinholeCamera(517.3, 516.5, 318.6, 255.3, 640, 480); }

TEST(PinholeCamera, ProjectMatchesIntrinsicMatrix) {
  const PinholeCamera cam = vgaCamera();
  const Vec3 p_c(0.4, -0.3, 2.5);
  const Vec3 uvw = cam.K() * p_c;
  EXPECT_LT((cam.project(p_c) - uvw.head<2>() / uvw.z()).norm(), 1e-12);
  EXPECT_LT((cam.project(Vec3(0.0, 0.0, 3.0)) - Vec2(318.6, 255.3)).norm(), 1e-12);
}

TEST(PinholeCamera, BackProjectInvertsProject) {
  const PinholeCamera cam = vgaCamera();
  for (const Vec3& p_c : {Vec3(0.4, -0.3, 2.5), Vec3(-1.2, 0.8, 0.4), Vec3(0.0, 0.0, 7.0)}) {
    EXPECT_LT((cam.backProject(cam.project(p_c), p_c.z()) - p_c).norm(), 1e-12);
  }
  const Vec2 u(12.5, 470.0);
  EXPECT_LT((cam.project(cam.backProject(u, 1.7)) - u).norm(), 1e-10);
  EXPECT_DOUBLE_EQ(cam.backProject(u, 1.7).z(), 1.7);
}

TEST(PinholeCamera, ProjectJacobianMatchesNumeric) {
  const PinholeCamera cam = vgaCamera();
  for (const Vec3& p_c : {Vec3(0.4, -0.3, 2.5), Vec3(-1.2, 0.8, 0.4), Vec3(0.0, 0.0, 1.0)}) {
    const Mat23 J = test::numericJacobian([&](const Vec3& p) { return cam.project(p); }, p_c);
    // Pixel Jacobians are O(fx / z) ~ 1e3; the central difference is good to ~1e-6 of that.
    EXPECT_LT((cam.projectJacobian(p_c) - J).cwiseAbs().maxCoeff(), 1e-4) << p_c.transpose();
  }
}

TEST(PinholeCamera, BackProjectJacobianMatchesNumeric) {
  const PinholeCamera cam = vgaCamera();
  for (const Vec3& u_depth :
       {Vec3(100.0, 200.0, 1.5), Vec3(600.0, 30.0, 4.0), Vec3(318.6, 255.3, 0.5)}) {
    const Mat3 J = test::numericJacobian(
        [&](const Vec3& x) { return cam.backProject(Vec2(x.x(), x.y()), x.z()); }, u_depth);
    EXPECT_LT((cam.backProjectJacobian(u_depth.head<2>(), u_depth.z()) - J).cwiseAbs().maxCoeff(),
              1e-9);
  }
}

TEST(PinholeCamera, ProjectionOfTransformedPointUnderPosePerturbation) {
  // The chain used by every reprojection edge: d project(T_c_w exp(d) p_w) / dd, right
  // perturbation.
  const PinholeCamera cam = vgaCamera();
  const SE3 T_c_w(so3ExpQuat(Vec3(0.1, -0.2, 0.05)), Vec3(0.2, -0.1, 0.5));
  const Vec3 p_w(0.3, 0.2, 3.0);
  const Vec3 p_c = T_c_w * p_w;
  Mat36 d_p_d_xi;
  d_p_d_xi << -T_c_w.rotationMatrix() * hat(p_w), T_c_w.rotationMatrix();
  const Eigen::Matrix<double, 2, 6> analytic = cam.projectJacobian(p_c) * d_p_d_xi;
  const Eigen::Matrix<double, 2, 6> numeric = test::numericJacobianOnManifold<6>(
      [&](const SE3& T) { return cam.project(T * p_w); }, T_c_w,
      [](const SE3& T, const Vec6& d) { return T * SE3::exp(d); });
  EXPECT_LT((analytic - numeric).cwiseAbs().maxCoeff(), 1e-4);
}

TEST(PinholeCamera, IsInImageRespectsBorder) {
  const PinholeCamera cam = vgaCamera();
  EXPECT_TRUE(cam.isInImage(Vec2(0.0, 0.0)));
  EXPECT_TRUE(cam.isInImage(Vec2(639.0, 479.0)));
  EXPECT_FALSE(cam.isInImage(Vec2(639.01, 100.0)));
  EXPECT_FALSE(cam.isInImage(Vec2(100.0, -0.01)));
  EXPECT_FALSE(cam.isInImage(Vec2(5.0, 100.0), /*border_px=*/8.0));
  EXPECT_TRUE(cam.isInImage(Vec2(8.0, 471.0), /*border_px=*/8.0));
}

TEST(PinholeCamera, ScaledKeepsPixelCentresConsistent) {
  const PinholeCamera cam = vgaCamera();
  const PinholeCamera half = cam.scaled(0.5);
  EXPECT_EQ(half.width(), 320);
  EXPECT_EQ(half.height(), 240);
  EXPECT_DOUBLE_EQ(half.fx(), 0.5 * 517.3);
  // A point's pixel in the half image is 0.5 * (u + 0.5) - 0.5 of its full-size pixel.
  const Vec3 p_c(0.7, -0.4, 2.2);
  const Vec2 u_full = cam.project(p_c);
  const Vec2 u_half = half.project(p_c);
  EXPECT_LT((u_half - (0.5 * (u_full + Vec2(0.5, 0.5)) - Vec2(0.5, 0.5))).norm(), 1e-12);
}

}  // namespace
}  // namespace ltlo
