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

/// Where a frame's IMU interval lies against its camera stamps (the online camera-IMU time offset,
/// LocalMapping.EstimateTimeOffset): [imu_begin_s + shift_begin_s, imu_end_s + shift_end_s] of the
/// input. The begin is the previous frame's end, so consecutive intervals tile the IMU's time axis
/// while the estimate moves; ImuShiftRamp gives them.
struct ImuCut {
  double shift_begin_s = 0.0;
  double shift_end_s = 0.0;
};

/// Hands out each frame's ImuCut: the end follows the mapper's estimate by at most max_step_s per
/// frame (a first estimate of 30 ms bends no single frame's prediction by it), the begin is the
/// previous end. Tracking thread only.
class ImuShiftRamp {
 public:
  explicit ImuShiftRamp(double max_step_s = 0.002) : max_step_s_(max_step_s) {}
  ImuCut next(double target_shift_s);
  double current_s() const { return shift_s_; }
  /// Continues from a saved run's ramp (a run resumed from an atlas file).
  void restore(double shift_s) { shift_s_ = shift_s; }

 private:
  double max_step_s_;
  double shift_s_ = 0.0;
};

struct FrameBuilderOptions {
  double min_depth_m = 0.1;   ///< depth readings below are treated as missing (m)
  double max_depth_m = 10.0;  ///< depth readings above are treated as missing (m)
};

/// Stateless after construction; build() is const (the extractor is thread-safe).
class FrameBuilder {
 public:
  FrameBuilder(const OrbOptions& orb, const SensorCalib& calib, const FrameBuilderOptions& options = {});

  /// Features and depths of `input`. With an IMU (calib.has_imu and >= 2 samples in the interval)
  /// the frame's imu_from_last_frame is the preintegration of the interval `cut` gives (all of
  /// input.imu when the reader gave no margin and the cut is zero) linearised at `bias`.
  map::Frame build(const io::RgbdImuFrame& input, const imu::ImuBias& bias = imu::ImuBias(), const ImuCut& cut = {}) const;

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
