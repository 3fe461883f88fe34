#pragma once
/// FrameBuilder: one RGB-D(-inertial) input frame -> map::Frame (grey conversion, ORB extraction,
/// per-keypoint depth within the valid range, back-projected points, all-static segmentation, and
/// the IMU preintegrated since the previous frame). With a distorting lens (Camera.k1...), ORB runs
/// on the raw image, each keypoint's depth is read at its raw pixel (depth is registered to the raw
/// colour grid), and the keypoints are then moved to the ideal pinhole image by the Undistorter's
/// lookup: the Frame, and everything after it, sees an ideal pinhole camera.
#include <memory>
#include <optional>

#include "ltlo/core/calib.h"
#include "ltlo/core/settings.h"
#include "ltlo/core/undistorter.h"
#include "ltlo/features/orb_extractor.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/map/frame.h"

namespace ltlo::tracking {

struct FrameBuilderOptions {
  double min_depth_m = 0.1;   ///< depth readings below are treated as missing (m)
  double max_depth_m = 10.0;  ///< depth readings above are treated as missing (m)
};

/// Stateless after construction; build() is const (the extractor is thread-safe).
class FrameBuilder {
 public:
  FrameBuilder(const OrbOptions& orb, const SensorCalib& calib, const FrameBuilderOptions& options = {});

  /// Features and depths of `input`. With an IMU (calib.has_imu and >= 2 samples in input.imu) the
  /// frame's imu_from_last_frame is the preintegration of input.imu linearised at `bias`.
  map::Frame build(const io::RgbdImuFrame& input, const imu::ImuBias& bias = imu::ImuBias()) const;

  const features::OrbExtractor& extractor() const { return extractor_; }
  const SensorCalib& calib() const { return calib_; }
  /// The lens' tables (inactive without distortion), shared with the stages that remap images.
  const std::shared_ptr<const Undistorter>& undistorter() const { return undistorter_; }

 private:
  features::OrbExtractor extractor_;
  SensorCalib calib_;
  std::shared_ptr<const Undistorter> undistorter_;
  FrameBuilderOptions options_;
};

}  // namespace ltlo::tracking
