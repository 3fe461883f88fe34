#pragma once
/// Sensor calibration of a sequence (DATA_FORMAT.md calib.yaml, ORB-SLAM3-style keys).
#include <string>

#include "ltlo/core/camera.h"
#include "ltlo/core/camera_model.h"
#include "ltlo/core/lie.h"

namespace ltlo {

class SettingsFile;

/// Colour camera with registered depth (the depth image shares the colour image's raw pixel grid).
struct CameraCalib {
  PinholeCamera camera;           ///< Camera.fx/fy/cx/cy (px), Camera.width/height (px)
  /// Camera.type and the distortion keys (ORB-SLAM3's names): "PinHole" with optional Camera.k1,
  /// k2, p1, p2, k3 (radial-tangential; all zero or absent = no lens); "Rational" with Camera.k1..k6,
  /// p1, p2 (OpenCV's 8-coefficient model); "KannalaBrandt8" with Camera.k1..k4 (equidistant).
  LensDistortion lens;
  double fps = 30.0;              ///< Camera.fps (Hz)
  double depth_map_factor = 1000; ///< DepthMapFactor: metres = png value / factor

  /// The camera as it delivers its raw images (K with the lens).
  CameraModel model() const { return CameraModel(camera, lens); }

  /// Reads and validates the Camera.* keys and DepthMapFactor; throws ConfigError (a lens that cannot
  /// be inverted over the whole image is refused, naming its first coefficient).
  static CameraCalib load(const SettingsFile& file);
};

/// IMU noise model (continuous-time densities) and camera extrinsic.
struct ImuCalib {
  SE3 T_b_c;                  ///< IMU.T_b_c1: camera pose in the body (IMU) frame
  double noise_gyro = 1.7e-4; ///< IMU.NoiseGyro (rad/s/sqrt(Hz))
  double noise_acc = 2.0e-3;  ///< IMU.NoiseAcc (m/s^2/sqrt(Hz))
  double gyro_walk = 1.9e-5;  ///< IMU.GyroWalk (rad/s^2/sqrt(Hz))
  double acc_walk = 3.0e-3;   ///< IMU.AccWalk (m/s^3/sqrt(Hz))
  double rate_hz = 200.0;     ///< IMU.Frequency (Hz)
  /// IMU.TimeOffset (s), Kalibr's timeshift_cam_imu: t_imu = t_cam + offset, i.e. the IMU stamps an
  /// instant `offset` later than the camera does. Readers shift the IMU stamps onto the camera's
  /// clock by it; the online estimate (Tracking.EstimateTimeOffset) refines what remains. [-0.2, 0.2]
  double time_offset_s = 0.0;

  /// Reads and validates the IMU.* keys; throws ConfigError.
  static ImuCalib load(const SettingsFile& file);
};

/// Everything calib.yaml holds. `has_imu` is false when the file has no IMU.* keys (TUM RGB-D).
struct SensorCalib {
  CameraCalib camera;
  ImuCalib imu;
  bool has_imu = false;

  static SensorCalib load(const SettingsFile& file);
  static SensorCalib load(const std::string& path);
  /// Writes calib.yaml in the DATA_FORMAT.md layout (written as text: OpenCV refuses dotted keys).
  void write(const std::string& path) const;
};

}  // namespace ltlo
