// Records shared by the atlas file's sections and the run state (record_io.h, run_state_io.h):
// camera, images, segmentation, ORB features, the IMU preintegration and samples, whole frames.
#include "record_io.h"

#include <limits>
#include <string>

#include "bow/vocabulary.h"
#include "ltlo/map/run_state_io.h"

namespace ltlo::map {

namespace {

/// A keypoint coordinate (px): undistorted keypoints may lie a little outside the image, but not
/// beyond kMaxCoordinate, where the grid's and the label lookup's integer conversions would overflow
/// (found by fuzz_atlas: a keypoint at x = 1.5e10).
float readCoordinate(ByteReader& in, const char* what) {
  constexpr float kMaxCoordinate = 1 << 20;
  const std::uint64_t offset = in.fileOffset();
  const float v = in.finiteF32(what);
  if (v < -kMaxCoordinate || v > kMaxCoordinate) {
    in.failAt(offset, std::string(what) + " out of [-1048576, 1048576]", std::to_string(v));
  }
  return v;
}

}  // namespace

void writeCamera(const PinholeCamera& camera, ByteWriter& out) {
  out.f64(camera.fx());
  out.f64(camera.fy());
  out.f64(camera.cx());
  out.f64(camera.cy());
  out.i32(camera.width());
  out.i32(camera.height());
}

PinholeCamera readCamera(ByteReader& in) {
  const double fx = in.f64InRange("camera fx", 1e-6, 1e9);
  const double fy = in.f64InRange("camera fy", 1e-6, 1e9);
  const double cx = in.finiteF64("camera cx");
  const double cy = in.finiteF64("camera cy");
  const int width = in.i32InRange("camera width", 1, kMaxCameraSide);
  const int height = in.i32InRange("camera height", 1, kMaxCameraSide);
  return PinholeCamera(fx, fy, cx, cy, width, height);
}

void writeImage(const cv::Mat& image, int element_bytes, ByteWriter& out) {
  out.i32(image.rows);
  out.i32(image.cols);
  for (int r = 0; r < image.rows; ++r) {
    const std::uint8_t* row = image.ptr<std::uint8_t>(r);
    if (element_bytes == 1) {
      out.raw(row, static_cast<std::size_t>(image.cols));
    } else {
      const std::uint16_t* row16 = image.ptr<std::uint16_t>(r);
      for (int c = 0; c < image.cols; ++c) out.u16(row16[c]);
    }
  }
}

cv::Mat readImage(ByteReader& in, int element_bytes, const char* what) {
  const int rows = in.i32InRange(what, 0, kMaxImageSide);
  const int cols = in.i32InRange(what, 0, kMaxImageSide);
  if ((rows == 0) != (cols == 0))
    in.fail(std::string(what) + ": one side is zero", std::to_string(rows) + "x" + std::to_string(cols));
  if (rows == 0) return cv::Mat();
  const std::size_t bytes = static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols) * element_bytes;
  if (bytes > in.remaining())
    in.fail(std::string(what) + " exceeds the bytes left", std::to_string(rows) + "x" + std::to_string(cols));
  cv::Mat image(rows, cols, element_bytes == 1 ? CV_8U : CV_16U);
  for (int r = 0; r < rows; ++r) {
    if (element_bytes == 1) {
      in.raw(image.ptr<std::uint8_t>(r), static_cast<std::size_t>(cols), what);
    } else {
      std::uint16_t* row = image.ptr<std::uint16_t>(r);
      for (int c = 0; c < cols; ++c) row[c] = in.u16(what);
    }
  }
  return image;
}

std::vector<double> readScores(ByteReader& in, const char* what) {
  const std::uint64_t offset = in.fileOffset();
  const std::size_t n = in.count(what, 8);
  if (n < 1 || n > kMaxClusters)
    in.failAt(offset, std::string(what) + ": cluster count out of [1, 256]", std::to_string(n));
  std::vector<double> scores(n);
  for (double& g : scores) g = in.f64InRange(what, 0.0, 1.0);
  return scores;
}

void writeSegmentation(const ClusterSegmentation& segmentation, ByteWriter& out) {
  writeImage(segmentation.labels, 1, out);
  out.i32(segmentation.scale);
  out.u64(segmentation.gamma.size());
  for (const double g : segmentation.gamma) out.f64(g);
  out.u64(segmentation.pixel_counts.size());
  for (const int count : segmentation.pixel_counts) out.i32(count);
  out.u64(segmentation.neighbours.size());
  for (const auto& [a, b] : segmentation.neighbours) {
    out.i32(a);
    out.i32(b);
  }
  writeImage(segmentation.depth_mm, 2, out);
  out.i32(segmentation.depth_scale);
}

ClusterSegmentation readSegmentation(ByteReader& in) {
  ClusterSegmentation segmentation;
  const std::uint64_t labels_offset = in.fileOffset();
  segmentation.labels = readImage(in, 1, "segmentation labels");
  segmentation.scale = in.i32InRange("segmentation scale", 1, kMaxScale);
  segmentation.gamma = readScores(in, "segmentation gamma");
  const int num_clusters = segmentation.numClusters();
  if (!segmentation.labels.empty()) {
    double min_label = 0.0, max_label = 0.0;
    cv::minMaxLoc(segmentation.labels, &min_label, &max_label);
    if (max_label >= num_clusters) {
      in.failAt(labels_offset, "segmentation label beyond the " + std::to_string(num_clusters) + " clusters",
                std::to_string(static_cast<int>(max_label)));
    }
  }
  const std::uint64_t counts_offset = in.fileOffset();
  const std::size_t num_counts = in.count("segmentation pixel counts", 4);
  if (num_counts != 0 && num_counts != segmentation.gamma.size()) {
    in.failAt(counts_offset, "pixel counts for " + std::to_string(num_clusters) + " clusters",
              std::to_string(num_counts));
  }
  segmentation.pixel_counts.resize(num_counts);
  for (int& count : segmentation.pixel_counts)
    count = in.i32InRange("segmentation pixel count", 0, std::numeric_limits<std::int32_t>::max());
  const std::size_t num_neighbours = in.count("segmentation neighbours", 8);
  segmentation.neighbours.reserve(num_neighbours);
  for (std::size_t k = 0; k < num_neighbours; ++k) {
    const std::uint64_t offset = in.fileOffset();
    const int a = in.i32("segmentation neighbour");
    const int b = in.i32("segmentation neighbour");
    if (!(a >= 0 && a < b && b < num_clusters)) {
      in.failAt(offset, "segmentation neighbour pair out of range", std::to_string(a) + ", " + std::to_string(b));
    }
    segmentation.neighbours.emplace_back(a, b);
  }
  segmentation.depth_mm = readImage(in, 2, "segmentation depth");
  segmentation.depth_scale = in.i32InRange("segmentation depth scale", 1, kMaxScale);
  return segmentation;
}

void writeFeatures(const std::vector<features::Keypoint>& keypoints,
                   const std::vector<features::Descriptor>& descriptors, ByteWriter& out) {
  out.u64(keypoints.size());
  for (const features::Keypoint& kp : keypoints) {
    out.f32(kp.x_px);
    out.f32(kp.y_px);
    out.f32(kp.angle_deg);
    out.f32(kp.response);
    out.i32(kp.octave);
  }
  for (const features::Descriptor& d : descriptors) {
    for (const std::uint64_t word : d) out.u64(word);
  }
}

features::OrbFeatures readFeatures(ByteReader& in) {
  const std::size_t n = in.count("keypoints", kKeypointBytes);
  features::OrbFeatures features;
  features.keypoints.resize(n);
  for (features::Keypoint& kp : features.keypoints) {
    kp.x_px = readCoordinate(in, "keypoint x");
    kp.y_px = readCoordinate(in, "keypoint y");
    kp.angle_deg = in.finiteF32("keypoint angle");
    kp.response = in.finiteF32("keypoint response");
    kp.octave = in.i32InRange("keypoint octave", 0, static_cast<std::int32_t>(kMaxPyramidLevels) - 1);
  }
  features.descriptors.resize(n);
  for (features::Descriptor& d : features.descriptors) {
    for (std::uint64_t& word : d) word = in.u64("descriptor");
  }
  return features;
}

std::vector<float> readScaleFactors(ByteReader& in, const features::OrbFeatures& features) {
  const std::uint64_t offset = in.fileOffset();
  const std::size_t levels = in.count("scale factors", 4);
  if (levels < 1 || levels > kMaxPyramidLevels)
    in.failAt(offset, "scale factor count out of [1, 64]", std::to_string(levels));
  std::vector<float> scale_factors(levels);
  for (float& s : scale_factors) {
    const std::uint64_t at = in.fileOffset();
    s = in.finiteF32("scale factor");
    if (!(s > 0.0f)) in.failAt(at, "scale factor is not positive", std::to_string(s));
  }
  for (const features::Keypoint& kp : features.keypoints) {
    if (kp.octave >= static_cast<int>(levels))
      in.fail("keypoint octave beyond the pyramid levels", std::to_string(kp.octave));
  }
  return scale_factors;
}

std::vector<float> readDepths(ByteReader& in, std::size_t n) {
  std::vector<float> depths(n);
  for (float& d : depths) {
    const std::uint64_t at = in.fileOffset();
    d = in.finiteF32("keypoint depth");
    if (d < 0.0f) in.failAt(at, "keypoint depth is negative", std::to_string(d));
  }
  return depths;
}

void writePreintegration(const imu::Preintegrated& preintegration, ByteWriter& out) {
  out.vec3(preintegration.bias().b_g);
  out.vec3(preintegration.bias().b_a);
  const imu::ImuNoise& noise = preintegration.noise();
  out.f64(noise.gyro_density);
  out.f64(noise.acc_density);
  out.f64(noise.gyro_walk_density);
  out.f64(noise.acc_walk_density);
  out.f64(noise.nominal_dt_s);
  out.f64(preintegration.shiftBegin_s());
  out.f64(preintegration.shiftEnd_s());
  out.u64(preintegration.steps().size());
  for (const imu::Preintegrated::Step& step : preintegration.steps()) {
    out.vec3(step.gyro_mean_rad_s);
    out.vec3(step.acc_mean_m_s2);
    out.f64(step.dt_s);
  }
}

imu::Preintegrated readPreintegration(ByteReader& in) {
  imu::ImuBias bias;
  bias.b_g = in.vec3("preintegration gyro bias");
  bias.b_a = in.vec3("preintegration accelerometer bias");
  imu::ImuNoise noise;
  noise.gyro_density = in.f64InRange("gyro noise density", 0.0, 1e6);
  noise.acc_density = in.f64InRange("accelerometer noise density", 0.0, 1e6);
  noise.gyro_walk_density = in.f64InRange("gyro random walk", 0.0, 1e6);
  noise.acc_walk_density = in.f64InRange("accelerometer random walk", 0.0, 1e6);
  noise.nominal_dt_s = in.f64InRange("nominal IMU period", 0.0, 1e6);
  const double shift_begin_s = in.finiteF64("preintegration begin shift");
  const double shift_end_s = in.finiteF64("preintegration end shift");
  const std::size_t num_steps = in.count("preintegration steps", 7 * 8);
  imu::Preintegrated preintegration(bias, noise);
  for (std::size_t k = 0; k < num_steps; ++k) {
    const Vec3 gyro = in.vec3("step gyro");
    const Vec3 acc = in.vec3("step accelerometer");
    const double dt_s = in.f64InRange("step dt", std::numeric_limits<double>::min(), 1e6);
    preintegration.integrateStep(gyro, acc, dt_s);
  }
  preintegration.setShifts(shift_begin_s, shift_end_s);
  return preintegration;
}

void writeOptionalPreintegration(const std::optional<imu::Preintegrated>& preintegration, ByteWriter& out) {
  out.boolean(preintegration.has_value());
  if (preintegration) writePreintegration(*preintegration, out);
}

std::optional<imu::Preintegrated> readOptionalPreintegration(ByteReader& in) {
  if (!in.boolean("has a preintegration")) return std::nullopt;
  return readPreintegration(in);
}

void writeImuSamples(const ImuSamples& samples, ByteWriter& out) {
  out.u64(samples.size());
  for (const ImuSample& sample : samples) {
    out.f64(sample.t_s);
    out.vec3(sample.gyro_rad_s);
    out.vec3(sample.acc_m_s2);
  }
}

ImuSamples readImuSamples(ByteReader& in, const char* what) {
  const std::size_t n = in.count(what, 7 * 8);
  ImuSamples samples(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint64_t offset = in.fileOffset();
    samples[k].t_s = in.finiteF64(what);
    if (k > 0 && samples[k].t_s < samples[k - 1].t_s) {
      in.failAt(offset, std::string(what) + ": stamps out of order", exactNumberText(samples[k].t_s));
    }
    samples[k].gyro_rad_s = in.vec3(what);
    samples[k].acc_m_s2 = in.vec3(what);
  }
  return samples;
}

void writeOptionalSe3(const std::optional<SE3>& T, ByteWriter& out) {
  out.boolean(T.has_value());
  if (T) out.se3(*T);
}

std::optional<SE3> readOptionalSe3(ByteReader& in, const char* what) {
  if (!in.boolean(what)) return std::nullopt;
  return in.se3(what);
}

void writeBias(const imu::ImuBias& bias, ByteWriter& out) {
  out.vec3(bias.b_g);
  out.vec3(bias.b_a);
}

imu::ImuBias readBias(ByteReader& in, const char* what) {
  imu::ImuBias bias;
  bias.b_g = in.vec3(what);
  bias.b_a = in.vec3(what);
  return bias;
}

void writeFrame(const Frame& frame, ByteWriter& out) {
  out.f64(frame.t_s());
  writeCamera(frame.camera(), out);
  out.se3(frame.T_b_c());
  writeFeatures(frame.keypoints(), frame.descriptors(), out);
  out.u64(frame.scaleFactors().size());
  for (const float s : frame.scaleFactors()) out.f32(s);
  for (const float d : frame.depths_m()) out.f32(d);
  writeSegmentation(frame.segmentation(), out);
  out.f64(frame.staticThreshold());
  out.boolean(frame.hasBow());
  writeOptionalSe3(frame.hasPose() ? std::optional<SE3>(frame.T_w_b()) : std::nullopt, out);
  out.vec3(frame.v_w_b());
  writeBias(frame.bias(), out);
  writeOptionalPreintegration(frame.imu_from_last_keyframe, out);
  writeOptionalPreintegration(frame.imu_from_last_frame, out);
  writeImuSamples(frame.imu_samples, out);
  out.boolean(frame.at_rest);
  out.u64(frame.reference_keyframe.value);
  for (const MapPointId id : frame.map_points) out.u64(id.value);
  for (const bool outlier : frame.outliers) out.boolean(outlier);
}

Frame readFrame(ByteReader& in, const bow::Vocabulary* vocabulary) {
  const double t_s = in.finiteF64("frame time");
  const PinholeCamera camera = readCamera(in);
  const SE3 T_b_c = in.se3("frame T_b_c");
  features::OrbFeatures features = readFeatures(in);
  std::vector<float> scale_factors = readScaleFactors(in, features);
  const std::size_t n = features.keypoints.size();
  std::vector<float> depths = readDepths(in, n);
  ClusterSegmentation segmentation = readSegmentation(in);
  const double static_threshold = in.finiteF64("frame static threshold");
  Frame frame(t_s, camera, T_b_c, std::move(features), std::move(depths), std::move(scale_factors));
  frame.setSegmentation(std::move(segmentation), static_threshold);
  const bool has_bow = in.boolean("frame has a BoW");
  if (const std::optional<SE3> T_w_b = readOptionalSe3(in, "frame pose")) frame.setPose_T_w_b(*T_w_b);
  frame.setVelocity(in.vec3("frame velocity"));
  frame.setBias(readBias(in, "frame bias"));
  frame.imu_from_last_keyframe = readOptionalPreintegration(in);
  frame.imu_from_last_frame = readOptionalPreintegration(in);
  frame.imu_samples = readImuSamples(in, "frame IMU samples");
  frame.at_rest = in.boolean("frame at rest");
  frame.reference_keyframe = KeyFrameId(in.u64("frame reference keyframe"));
  // The matches' counts are the keypoints'; each entry is at least one byte.
  if (n > in.remaining()) in.fail("frame matches exceed the bytes left", std::to_string(n));
  for (MapPointId& id : frame.map_points) id = MapPointId(in.u64("frame map point"));
  for (std::size_t i = 0; i < n; ++i) frame.outliers[i] = in.boolean("frame outlier flag");
  if (has_bow && vocabulary != nullptr) frame.computeBow(*vocabulary);
  return frame;
}

}  // namespace ltlo::map
