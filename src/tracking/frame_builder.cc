#include "ltlo/tracking/frame_builder.h"

#include <algorithm>

#include <opencv2/imgproc.hpp>

#include "ltlo/core/assert.h"

namespace ltlo::tracking {

FrameBuilder::FrameBuilder(const OrbOptions& orb, const SensorCalib& calib, const FrameBuilderOptions& options)
    : extractor_(orb),
      calib_(calib),
      undistorter_(std::make_shared<const Undistorter>(calib.camera.model())),
      options_(options) {
  LTLO_ASSERT(options_.min_depth_m >= 0.0 && options_.max_depth_m > options_.min_depth_m,
              "depth range [" << options_.min_depth_m << ", " << options_.max_depth_m << "] m is empty");
}

ImuCut ImuShiftRamp::next(double target_shift_s) {
  ImuCut cut;
  cut.shift_begin_s = shift_s_;
  shift_s_ += std::clamp(target_shift_s - shift_s_, -max_step_s_, max_step_s_);
  cut.shift_end_s = shift_s_;
  return cut;
}

map::Frame FrameBuilder::build(const io::RgbdImuFrame& input, const imu::ImuBias& bias, const ImuCut& cut) const {
  cv::Mat gray;
  if (input.color_bgr.channels() == 3) {
    cv::cvtColor(input.color_bgr, gray, cv::COLOR_BGR2GRAY);
  } else {
    gray = input.color_bgr;
  }
  LTLO_ASSERT(gray.type() == CV_8UC1, "frame " << input.index << " (" << input.color_path
                                               << "): expected an 8-bit image, OpenCV type " << gray.type());
  features::OrbFeatures features = extractor_.extract(gray);
  std::vector<float> depths = map::depthsAtKeypoints(input.depth_m, features.keypoints);
  for (float& d : depths) {
    if (d < options_.min_depth_m || d > options_.max_depth_m) d = 0.0f;
  }
  if (undistorter_->active()) {
    for (features::Keypoint& kp : features.keypoints) undistorter_->undistortPoint(kp.x_px, kp.y_px, &kp.x_px, &kp.y_px);
  }
  const SE3 T_b_c = calib_.has_imu ? calib_.imu.T_b_c : SE3();
  map::Frame frame(input.t_s, calib_.camera.camera, T_b_c, std::move(features), std::move(depths),
                   extractor_.scaleFactors());
  if (calib_.has_imu && !input.imu.empty()) {
    const bool exact = !input.imu_has_margin && cut.shift_begin_s == 0.0 && cut.shift_end_s == 0.0;
    const ImuSamples shifted =
        exact ? ImuSamples() : imuSamplesBetween(input.imu, input.imu_begin_s + cut.shift_begin_s, input.imu_end_s + cut.shift_end_s);
    const ImuSamples& samples = exact ? input.imu : shifted;
    if (samples.size() >= 2) {
      imu::Preintegrated pim(bias, imu::ImuNoise::fromCalib(calib_.imu));
      pim.integrate(samples);
      pim.setShifts(cut.shift_begin_s, cut.shift_end_s);
      frame.imu_from_last_frame = std::move(pim);
      frame.imu_samples = samples;
    }
  }
  return frame;
}

}  // namespace ltlo::tracking
