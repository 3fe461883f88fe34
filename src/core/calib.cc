#include "ltlo/core/calib.h"

#include <fstream>
#include <iomanip>
#include <limits>
#include <optional>
#include <sstream>

#include "ltlo/core/errors.h"
#include "ltlo/core/settings_file.h"

namespace ltlo {
namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kMaxCoefficient = 100.0;  // |k|, |p| beyond this is no lens we know of

// Reads the lens of `type`; coefficients absent from the file are 0 (ORB-SLAM3 files often omit k3).
LensDistortion loadLens(const SettingsFile& file, const std::string& type) {
  LensDistortion lens;
  auto coefficient = [&](const char* name) {
    return file.getDouble(std::string("Camera.") + name, 0.0, -kMaxCoefficient, kMaxCoefficient);
  };
  if (type == "PinHole") {
    lens.model = LensModel::kRadTan;
    lens.k1 = coefficient("k1");
    lens.k2 = coefficient("k2");
    lens.p1 = coefficient("p1");
    lens.p2 = coefficient("p2");
    lens.k3 = coefficient("k3");
    if (!lens.isDistorted()) lens.model = LensModel::kPinhole;
  } else if (type == "Rational") {
    lens.model = LensModel::kRational;
    lens.k1 = coefficient("k1");
    lens.k2 = coefficient("k2");
    lens.p1 = coefficient("p1");
    lens.p2 = coefficient("p2");
    lens.k3 = coefficient("k3");
    lens.k4 = coefficient("k4");
    lens.k5 = coefficient("k5");
    lens.k6 = coefficient("k6");
  } else {  // "KannalaBrandt8": every coefficient is part of the model
    lens.model = LensModel::kKannalaBrandt;
    lens.k1 = file.getDouble("Camera.k1", -kMaxCoefficient, kMaxCoefficient);
    lens.k2 = file.getDouble("Camera.k2", -kMaxCoefficient, kMaxCoefficient);
    lens.k3 = file.getDouble("Camera.k3", -kMaxCoefficient, kMaxCoefficient);
    lens.k4 = file.getDouble("Camera.k4", -kMaxCoefficient, kMaxCoefficient);
  }
  return lens;
}

// Every raw pixel of the border (and a grid inside) must undistort and distort back to itself: a
// lens model that folds over inside the image (a typo in a coefficient, often) would give keypoints
// two places. Returns the first pixel that fails, if any.
std::optional<Vec2> firstNonInvertiblePixel(const CameraModel& model) {
  const int w = model.pinhole().width(), h = model.pinhole().height();
  auto fails = [&](double x, double y) {
    const Vec2 u(x, y);
    const std::optional<Vec2> ideal = model.undistortPixel(u);
    return !ideal || (model.distortPixel(*ideal) - u).norm() > 1e-6;
  };
  for (int c = 0; c < w; ++c) {
    if (fails(c, 0)) return Vec2(c, 0);
    if (fails(c, h - 1)) return Vec2(c, h - 1);
  }
  for (int r = 0; r < h; ++r) {
    if (fails(0, r)) return Vec2(0, r);
    if (fails(w - 1, r)) return Vec2(w - 1, r);
  }
  for (int r = 0; r < h; r += 16) {
    for (int c = 0; c < w; c += 16) {
      if (fails(c, r)) return Vec2(c, r);
    }
  }
  return std::nullopt;
}

}  // namespace

CameraCalib CameraCalib::load(const SettingsFile& file) {
  CameraCalib calib;
  // Optional, for ORB-SLAM3-style files; only the pinhole model exists here.
  const std::string type = file.getString("Camera.type", "PinHole");
  if (type != "PinHole" && type != "Rational" && type != "KannalaBrandt8") {
    file.fail("Camera.type", "\"" + type + "\"", "\"PinHole\", \"Rational\" or \"KannalaBrandt8\"");
  }
  const int width = file.getInt("Camera.width", 1, 16384);
  const int height = file.getInt("Camera.height", 1, 16384);
  const double fx = file.getDouble("Camera.fx", 1e-3, kInf);
  const double fy = file.getDouble("Camera.fy", 1e-3, kInf);
  const double cx = file.getDouble("Camera.cx", -width, 2.0 * width);
  const double cy = file.getDouble("Camera.cy", -height, 2.0 * height);
  calib.camera = PinholeCamera(fx, fy, cx, cy, width, height);
  calib.lens = loadLens(file, type);
  if (calib.lens.isDistorted()) {
    if (const std::optional<Vec2> pixel = firstNonInvertiblePixel(calib.model())) {
      std::ostringstream expected;
      expected << "a lens that can be inverted over the whole " << width << "x" << height << " image (pixel ("
               << pixel->x() << ", " << pixel->y() << ") does not undistort and back; " << calib.lens.describe() << ")";
      std::string key = "Camera.k1";  // the key named: the first coefficient the file gives
      for (const char* name : {"Camera.k1", "Camera.k2", "Camera.p1", "Camera.p2", "Camera.k3", "Camera.k4",
                               "Camera.k5", "Camera.k6"}) {
        if (file.has(name)) {
          key = name;
          break;
        }
      }
      file.fail(key, file.valueText(key), expected.str());
    }
  }
  calib.fps = file.getDouble("Camera.fps", 1e-3, 1e4);
  calib.depth_map_factor = file.getDouble("DepthMapFactor", 1e-6, 1e9);
  return calib;
}

ImuCalib ImuCalib::load(const SettingsFile& file) {
  ImuCalib calib;
  const Mat4 T = file.getMatrix("IMU.T_b_c1", 4, 4);
  const Mat3 R = T.block<3, 3>(0, 0);
  if ((R.transpose() * R - Mat3::Identity()).norm() > 1e-3 || R.determinant() < 0.0 ||
      (T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
    file.fail("IMU.T_b_c1", "a matrix whose 3x3 block is not a rotation",
              "a rigid 4x4 transform [R t; 0 0 0 1]");
  }
  calib.T_b_c = SE3::fromMatrix(T);
  calib.noise_gyro = file.getDouble("IMU.NoiseGyro", 0.0, 10.0);
  calib.noise_acc = file.getDouble("IMU.NoiseAcc", 0.0, 100.0);
  calib.gyro_walk = file.getDouble("IMU.GyroWalk", 0.0, 10.0);
  calib.acc_walk = file.getDouble("IMU.AccWalk", 0.0, 100.0);
  calib.rate_hz = file.getDouble("IMU.Frequency", 1.0, 1e5);
  calib.time_offset_s = file.getDouble("IMU.TimeOffset", 0.0, -0.2, 0.2);
  return calib;
}

SensorCalib SensorCalib::load(const SettingsFile& file) {
  SensorCalib calib;
  calib.camera = CameraCalib::load(file);
  calib.has_imu = file.has("IMU.T_b_c1");
  if (calib.has_imu) calib.imu = ImuCalib::load(file);
  return calib;
}

SensorCalib SensorCalib::load(const std::string& path) { return load(SettingsFile(path)); }

void SensorCalib::write(const std::string& path) const {
  std::ofstream out(path);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  out << std::setprecision(17);
  const PinholeCamera& cam = camera.camera;
  out << "%YAML:1.0\n---\n";
  const LensDistortion& lens = camera.lens;
  const char* type = lens.model == LensModel::kRational        ? "Rational"
                     : lens.model == LensModel::kKannalaBrandt ? "KannalaBrandt8"
                                                               : "PinHole";
  out << "Camera.type: \"" << type << "\"\n";
  out << "Camera.fx: " << cam.fx() << "\nCamera.fy: " << cam.fy() << "\n";
  out << "Camera.cx: " << cam.cx() << "\nCamera.cy: " << cam.cy() << "\n";
  switch (lens.model) {
    case LensModel::kPinhole: break;
    case LensModel::kRadTan:
      out << "Camera.k1: " << lens.k1 << "\nCamera.k2: " << lens.k2 << "\nCamera.p1: " << lens.p1
          << "\nCamera.p2: " << lens.p2 << "\nCamera.k3: " << lens.k3 << "\n";
      break;
    case LensModel::kRational:
      out << "Camera.k1: " << lens.k1 << "\nCamera.k2: " << lens.k2 << "\nCamera.p1: " << lens.p1
          << "\nCamera.p2: " << lens.p2 << "\nCamera.k3: " << lens.k3 << "\nCamera.k4: " << lens.k4
          << "\nCamera.k5: " << lens.k5 << "\nCamera.k6: " << lens.k6 << "\n";
      break;
    case LensModel::kKannalaBrandt:
      out << "Camera.k1: " << lens.k1 << "\nCamera.k2: " << lens.k2 << "\nCamera.k3: " << lens.k3
          << "\nCamera.k4: " << lens.k4 << "\n";
      break;
  }
  out << "Camera.width: " << cam.width() << "\nCamera.height: " << cam.height() << "\n";
  out << "Camera.fps: " << camera.fps << "\n";
  out << "DepthMapFactor: " << camera.depth_map_factor << "\n";
  if (has_imu) {
    const Mat4 T = imu.T_b_c.matrix();
    out << "IMU.T_b_c1: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [ ";
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) out << T(r, c) << (r == 3 && c == 3 ? " ]\n" : ", ");
    }
    out << "IMU.NoiseGyro: " << imu.noise_gyro << "\nIMU.NoiseAcc: " << imu.noise_acc << "\n";
    out << "IMU.GyroWalk: " << imu.gyro_walk << "\nIMU.AccWalk: " << imu.acc_walk << "\n";
    out << "IMU.Frequency: " << imu.rate_hz << "\n";
    if (imu.time_offset_s != 0.0) out << "IMU.TimeOffset: " << imu.time_offset_s << "\n";
  }
  if (!out) throw InputError(path, 0, "write failed");
}

}  // namespace ltlo
