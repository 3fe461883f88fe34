#include "ltlo/core/calib.h"

#include <fstream>
#include <iomanip>
#include <limits>

#include "ltlo/core/errors.h"
#include "ltlo/core/settings_file.h"

namespace ltlo {
namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}

CameraCalib CameraCalib::load(const SettingsFile& file) {
  CameraCalib calib;
  // Optional, for ORB-SLAM3-style files; only the pinhole model exists here.
  const std::string type = file.getString("Camera.type", "PinHole");
  if (type != "PinHole") file.fail("Camera.type", "\"" + type + "\"", "\"PinHole\"");
  const int width = file.getInt("Camera.width", 1, 16384);
  const int height = file.getInt("Camera.height", 1, 16384);
  const double fx = file.getDouble("Camera.fx", 1e-3, kInf);
  const double fy = file.getDouble("Camera.fy", 1e-3, kInf);
  const double cx = file.getDouble("Camera.cx", -width, 2.0 * width);
  const double cy = file.getDouble("Camera.cy", -height, 2.0 * height);
  calib.camera = PinholeCamera(fx, fy, cx, cy, width, height);
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
  out << "Camera.type: \"PinHole\"\n";
  out << "Camera.fx: " << cam.fx() << "\nCamera.fy: " << cam.fy() << "\n";
  out << "Camera.cx: " << cam.cx() << "\nCamera.cy: " << cam.cy() << "\n";
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
  }
  if (!out) throw InputError(path, 0, "write failed");
}

}  // namespace ltlo
