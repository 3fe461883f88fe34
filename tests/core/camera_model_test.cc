// Camera models with lens distortion (include/ltlo/core/camera_model.h) and the Undistorter's
// tables (include/ltlo/core/undistorter.h): round trips of a pixel grid through each model,
// Jacobians against central differences, the keypoint lookup and the image remap, and calib.yaml's
// lens keys with their validation.
#include "ltlo/core/camera_model.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "common/numeric_jacobian.h"
#include "ltlo/core/calib.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/settings_file.h"
#include "ltlo/core/undistorter.h"

namespace ltlo {
namespace {

PinholeCamera vgaPinhole() { return PinholeCamera(525.0, 523.0, 319.5, 241.0, 640, 480); }

// About 24 px of barrel distortion at the VGA corners (the leads' test lens).
LensDistortion radTanLens() {
  LensDistortion lens;
  lens.model = LensModel::kRadTan;
  lens.k1 = -0.12;
  lens.k2 = 0.03;
  lens.p1 = 4e-4;
  lens.p2 = -6e-4;
  lens.k3 = -0.004;
  return lens;
}

// An Azure-Kinect-like colour lens: the 8-coefficient rational model of its factory calibration.
LensDistortion rationalLens() {
  LensDistortion lens;
  lens.model = LensModel::kRational;
  lens.k1 = 0.52;
  lens.k2 = -2.6;
  lens.k3 = 1.5;
  lens.k4 = 0.40;
  lens.k5 = -2.43;
  lens.k6 = 1.42;
  lens.p1 = 6e-4;
  lens.p2 = -3e-4;
  return lens;
}

// An equidistant lens of a wide camera.
LensDistortion kannalaBrandtLens() {
  LensDistortion lens;
  lens.model = LensModel::kKannalaBrandt;
  lens.k1 = -0.012;
  lens.k2 = 0.004;
  lens.k3 = -0.0015;
  lens.k4 = 0.0002;
  return lens;
}

std::vector<LensDistortion> allLenses() { return {radTanLens(), rationalLens(), kannalaBrandtLens()}; }

TEST(CameraModel, AGridOfPixelsGoesThroughEachModelAndBackWithin1e6Px) {
  for (const LensDistortion& lens : allLenses()) {
    const CameraModel model(vgaPinhole(), lens);
    double worst_px = 0.0, largest_shift_px = 0.0;
    for (int r = 0; r < 480; r += 8) {
      for (int c = 0; c < 640; c += 8) {
        const Vec2 u(c + 0.25, r + 0.75);
        const std::optional<Vec2> ideal = model.undistortPixel(u);
        ASSERT_TRUE(ideal.has_value()) << lensModelName(lens.model) << " at " << u.transpose();
        worst_px = std::max(worst_px, (model.distortPixel(*ideal) - u).norm());
        largest_shift_px = std::max(largest_shift_px, (*ideal - u).norm());
        // Through the 3-D ray as well: project(unproject(u) * depth) is u.
        const Vec3 ray = *model.unproject(u);
        worst_px = std::max(worst_px, (model.project(2.3 * ray) - u).norm());
      }
    }
    EXPECT_LT(worst_px, 1e-6) << lens.describe();
    EXPECT_GT(largest_shift_px, 3.0) << lens.describe() << ": the test lens should distort visibly";
  }
  // The radial-tangential test lens moves the corners by about 24 px.
  const CameraModel radtan(vgaPinhole(), radTanLens());
  const double corner_shift = (*radtan.undistortPixel(Vec2(0.0, 0.0)) - Vec2(0.0, 0.0)).norm();
  EXPECT_GT(corner_shift, 20.0);
  EXPECT_LT(corner_shift, 30.0);
}

TEST(CameraModel, ProjectionJacobiansMatchNumericDifferentiation) {
  for (const LensDistortion& lens : allLenses()) {
    const CameraModel model(vgaPinhole(), lens);
    for (const Vec3& p_c : {Vec3(0.4, -0.3, 2.5), Vec3(-0.9, 0.6, 1.4), Vec3(0.0, 0.0, 1.0), Vec3(0.7, 0.5, 1.1)}) {
      const Mat23 numeric = test::numericJacobian([&](const Vec3& p) { return model.project(p); }, p_c);
      // Pixel Jacobians are O(fx / z) ~ 1e3: the central difference is good to ~1e-6 of that.
      EXPECT_LT((model.projectJacobian(p_c) - numeric).cwiseAbs().maxCoeff(), 1e-4)
          << lens.describe() << " at " << p_c.transpose();
      const Vec2 x_n = p_c.head<2>() / p_c.z();
      const Mat2 numeric_distort = test::numericJacobian([&](const Vec2& x) { return lens.distort(x); }, x_n);
      EXPECT_LT((lens.distortJacobian(x_n) - numeric_distort).cwiseAbs().maxCoeff(), 1e-8) << lens.describe();
    }
    for (const Vec2& u : {Vec2(10.0, 12.0), Vec2(320.0, 240.0), Vec2(600.5, 30.25), Vec2(100.0, 470.0)}) {
      const Eigen::Matrix<double, 3, 2> numeric =
          test::numericJacobian([&](const Vec2& px) -> Vec3 { return *model.unproject(px); }, u, 1e-4);
      // Normalised units per pixel ~ 2e-3: compare to 1e-9.
      EXPECT_LT((model.unprojectJacobian(u) - numeric).cwiseAbs().maxCoeff(), 1e-9)
          << lens.describe() << " at " << u.transpose();
    }
  }
}

TEST(CameraModel, ZeroCoefficientsAreThePinholeBitForBit) {
  LensDistortion lens;
  lens.model = LensModel::kRadTan;  // a radtan file whose coefficients are all zero
  EXPECT_FALSE(lens.isDistorted());
  const CameraModel model(vgaPinhole(), lens);
  const Vec2 u(123.25, 401.5);
  EXPECT_EQ(*model.undistortPixel(u), u);
  const Undistorter undistorter(model);
  EXPECT_FALSE(undistorter.active());
  float x = 0.0f, y = 0.0f;
  undistorter.undistortPoint(123.25f, 401.5f, &x, &y);
  EXPECT_EQ(x, 123.25f);
  EXPECT_EQ(y, 401.5f);
}

TEST(Undistorter, TheKeypointLookupAgreesWithTheIterativeSolveToAThousandthOfAPixel) {
  for (const LensDistortion& lens : allLenses()) {
    const CameraModel model(vgaPinhole(), lens);
    const Undistorter undistorter(model);
    ASSERT_TRUE(undistorter.active());
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> col(0.0f, 639.0f), row(0.0f, 479.0f);
    double worst_px = 0.0;
    for (int k = 0; k < 2000; ++k) {
      const float x = col(rng), y = row(rng);
      float ux = 0.0f, uy = 0.0f;
      undistorter.undistortPoint(x, y, &ux, &uy);
      const Vec2 exact = *model.undistortPixel(Vec2(x, y));
      worst_px = std::max(worst_px, (Vec2(ux, uy) - exact).norm());
    }
    // Bilinear interpolation of a smooth map, float storage included: measured 2.0e-4 px (radtan),
    // 1.0e-4 px (rational), 9.4e-4 px (Kannala-Brandt, whose table values reach 1e3 px in float).
    EXPECT_LT(worst_px, 2e-3) << lens.describe();
  }
}

TEST(Undistorter, ARemappedImageIsTheIdealPinholeImage) {
  // A raw image of a smooth pattern seen through the lens: raw pixel u shows pattern(undistort(u)).
  const CameraModel model(vgaPinhole(), radTanLens());
  auto pattern = [](const Vec2& ideal) {
    return 128.0 + 60.0 * std::sin(ideal.x() / 23.0) + 50.0 * std::cos(ideal.y() / 17.0);
  };
  cv::Mat raw(480, 640, CV_32F);
  for (int r = 0; r < 480; ++r) {
    for (int c = 0; c < 640; ++c) raw.at<float>(r, c) = static_cast<float>(pattern(*model.undistortPixel(Vec2(c, r))));
  }
  const Undistorter undistorter(model);
  cv::Mat ideal, ideal_nearest;
  undistorter.toIdeal(raw, &ideal, cv::INTER_LINEAR);
  undistorter.toIdeal(raw, &ideal_nearest, cv::INTER_NEAREST);
  double worst_linear = 0.0;
  int checked = 0;
  for (int r = 20; r < 460; r += 5) {
    for (int c = 20; c < 620; c += 5) {
      worst_linear = std::max(worst_linear, std::abs(ideal.at<float>(r, c) - pattern(Vec2(c, r))));
      ++checked;
    }
  }
  EXPECT_GT(checked, 10000);
  // Bilinear sampling of a pattern of slope <= 3 per px (plus the remap's 1/32 px fixed point).
  EXPECT_LT(worst_linear, 0.5);
  // Nearest: within the pattern's change over half a pixel diagonal.
  EXPECT_LT(std::abs(ideal_nearest.at<float>(240, 320) - pattern(Vec2(320, 240))), 3.0);
  // Barrel distortion: the whole ideal image has a raw source.
  EXPECT_GT(undistorter.idealCoverage(), 0.999);
  // Back to raw: the raw pixel's position on the ideal grid at half resolution.
  const cv::Mat map = undistorter.rawToIdealMap(2);
  const Vec2 corner_ideal = *model.undistortPixel(Vec2(0.0, 0.0));
  EXPECT_NEAR(map.at<cv::Vec2f>(0, 0)[0], (corner_ideal.x() + 0.5) / 2.0 - 0.5, 1e-3);
  EXPECT_NEAR(map.at<cv::Vec2f>(0, 0)[1], (corner_ideal.y() + 0.5) / 2.0 - 0.5, 1e-3);
}

// calib.yaml with the given lines after a VGA pinhole.
std::string writeCalib(const std::string& name, const std::string& lens_lines) {
  const std::string path = (std::filesystem::temp_directory_path() / ("ltlo_camera_model_" + name + ".yaml")).string();
  std::ofstream out(path);
  out << "%YAML:1.0\n---\nCamera.fx: 525.0\nCamera.fy: 523.0\nCamera.cx: 319.5\nCamera.cy: 241.0\n"
      << "Camera.width: 640\nCamera.height: 480\nCamera.fps: 30.0\nDepthMapFactor: 1000.0\n"
      << lens_lines;
  return path;
}

std::string configErrorOf(const std::string& path) {
  try {
    SensorCalib::load(path);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(CameraCalib, ReadsEachLensModelInOrbSlam3Names) {
  {
    const SensorCalib calib = SensorCalib::load(writeCalib(
        "radtan", "Camera.type: \"PinHole\"\nCamera.k1: -0.12\nCamera.k2: 0.03\nCamera.p1: 0.0004\nCamera.p2: -0.0006\n"));
    EXPECT_EQ(calib.camera.lens.model, LensModel::kRadTan);
    EXPECT_DOUBLE_EQ(calib.camera.lens.k1, -0.12);
    EXPECT_DOUBLE_EQ(calib.camera.lens.k3, 0.0);  // absent: zero, as ORB-SLAM3 files often omit it
  }
  {
    const SensorCalib calib = SensorCalib::load(writeCalib(
        "rational", "Camera.type: \"Rational\"\nCamera.k1: 0.52\nCamera.k2: -2.6\nCamera.k3: 1.5\nCamera.k4: 0.4\n"
                    "Camera.k5: -2.43\nCamera.k6: 1.42\nCamera.p1: 0.0006\nCamera.p2: -0.0003\n"));
    EXPECT_EQ(calib.camera.lens.model, LensModel::kRational);
    EXPECT_DOUBLE_EQ(calib.camera.lens.k6, 1.42);
  }
  {
    const SensorCalib calib = SensorCalib::load(writeCalib(
        "kb", "Camera.type: \"KannalaBrandt8\"\nCamera.k1: -0.012\nCamera.k2: 0.004\nCamera.k3: -0.0015\nCamera.k4: 0.0002\n"));
    EXPECT_EQ(calib.camera.lens.model, LensModel::kKannalaBrandt);
    EXPECT_DOUBLE_EQ(calib.camera.lens.k4, 0.0002);
  }
  {
    const SensorCalib calib = SensorCalib::load(writeCalib("zeros", "Camera.k1: 0.0\nCamera.k2: 0.0\n"));
    EXPECT_FALSE(calib.camera.lens.isDistorted());
  }
}

TEST(CameraCalib, WritesTheLensAndReadsItBack) {
  SensorCalib calib = SensorCalib::load(writeCalib("write_source", ""));
  calib.camera.lens = rationalLens();
  const std::string path = (std::filesystem::temp_directory_path() / "ltlo_camera_model_written.yaml").string();
  calib.write(path);
  const SensorCalib back = SensorCalib::load(path);
  EXPECT_EQ(back.camera.lens.model, LensModel::kRational);
  EXPECT_DOUBLE_EQ(back.camera.lens.k1, 0.52);
  EXPECT_DOUBLE_EQ(back.camera.lens.k5, -2.43);
  EXPECT_DOUBLE_EQ(back.camera.lens.p2, -3e-4);
}

TEST(CameraCalib, MalformedLensKeysNameTheKeyAndValue) {
  const std::string text = configErrorOf(writeCalib("bad_text", "Camera.k1: abc\n"));
  EXPECT_NE(text.find("Camera.k1"), std::string::npos) << text;
  EXPECT_NE(text.find("abc"), std::string::npos) << text;

  const std::string range = configErrorOf(writeCalib("bad_range", "Camera.p2: 1000.0\n"));
  EXPECT_NE(range.find("Camera.p2 = 1000"), std::string::npos) << range;

  // A coefficient that folds the lens over inside the image.
  const std::string fold = configErrorOf(writeCalib("fold", "Camera.k1: -2.5\n"));
  EXPECT_NE(fold.find("Camera.k1 = -2.5"), std::string::npos) << fold;
  EXPECT_NE(fold.find("inverted over the whole 640x480 image"), std::string::npos) << fold;

  const std::string type = configErrorOf(writeCalib("bad_type", "Camera.type: \"Fisheye\"\n"));
  EXPECT_NE(type.find("Camera.type = \"Fisheye\""), std::string::npos) << type;

  // Kannala-Brandt needs all four coefficients.
  const std::string missing = configErrorOf(writeCalib("kb_missing", "Camera.type: \"KannalaBrandt8\"\nCamera.k1: 0.01\n"));
  EXPECT_NE(missing.find("Camera.k2"), std::string::npos) << missing;
}

}  // namespace
}  // namespace ltlo
