#pragma once
/// Streaming reader of RGB-D(-inertial) sequences: the DATA_FORMAT.md layout (also plain TUM
/// RGB-D without IMU), the OpenLORIS-Scene layout, and EuRoC-style imu0/data.csv. Index files,
/// IMU and ground truth are read and checked when the reader is opened; images are loaded one
/// frame at a time by next(). Bad input throws InputError naming the file, the line and the value.
#include <atomic>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "ltlo/core/calib.h"
#include "ltlo/core/sequence_options.h"
#include "ltlo/io/bag_topics.h"
#include "ltlo/io/imu_io.h"
#include "ltlo/io/trajectory_io.h"

namespace ltlo::io {

/// One RGB-D pair with the IMU samples since the previous frame.
struct RgbdImuFrame {
  int index = 0;           ///< 0-based position in the sequence
  double t_s = 0.0;        ///< colour image timestamp
  double depth_t_s = 0.0;  ///< depth image timestamp (associated to t_s)
  cv::Mat color_bgr;       ///< CV_8UC3, BGR as OpenCV reads it
  cv::Mat depth_m;         ///< CV_32F metres, 0 = no reading (png value / DepthMapFactor)
  std::string color_path;
  std::string depth_path;
  std::string mask_path;  ///< ground-truth mask file (masks/), empty when absent or not read
  cv::Mat mask;           ///< CV_8UC1, 255 = dynamic, 0 = static; empty when absent or not read
                          ///< (SequenceReaderOptions::read_masks)
  /// Samples in [imu_begin_s - margin, imu_end_s + margin] (SequenceReaderOptions::imu_margin_s,
  /// default 0) with interpolated samples at both ends (the boundary sample is shared by consecutive
  /// frames), on the camera's clock (IMU.TimeOffset applied). The first frame holds the single
  /// sample at t_s (without margin). Empty without IMU or where the IMU stream does not reach.
  ImuSamples imu;
  /// The frame's own interval: from the previous frame's colour time to t_s (the first frame: t_s).
  /// A consumer that estimates a remaining clock offset cuts [imu_begin_s + shift, imu_end_s + shift']
  /// out of `imu` (|shift| <= margin).
  double imu_begin_s = 0.0;
  double imu_end_s = 0.0;
  bool imu_has_margin = false;  ///< `imu` reaches beyond [imu_begin_s, imu_end_s] (a margin was asked for)
};

/// Where one frame's files are and which index lines named them (for messages).
struct FrameFiles {
  double t_s = 0.0;        ///< colour timestamp
  double depth_t_s = 0.0;  ///< depth timestamp
  std::string color_path;
  std::string depth_path;
  std::string mask_path;        ///< empty when the sequence has no mask for this frame
  std::string color_list_path;  ///< index file that named the colour image, and its line
  int color_list_line = 0;
  std::string depth_list_path;  ///< index file that named the depth image, and its line
  int depth_list_line = 0;
};

enum class SequenceLayout {
  kDataFormat,  ///< rgb/, depth/, associations.txt or rgb.txt + depth.txt, imu.txt, calib.yaml
  kOpenLoris,   ///< color/, aligned_depth/, color.txt, aligned_depth.txt, accel.txt, gyro.txt
};

/// Looks at the folder's files: color.txt -> kOpenLoris; associations.txt or rgb.txt ->
/// kDataFormat; otherwise throws InputError listing what was expected.
SequenceLayout detectLayout(const std::string& sequence_dir);

namespace detail {
class BagSource;  // bag_reader.cc: the open bag and its message index
}

/// Reading choices beyond SequenceOptions.
struct SequenceReaderOptions {
  SequenceOptions sequence;  ///< IMU gap limit and policy
  /// Replaces SEQ/calib.yaml (required for OpenLORIS, whose folders have no calib.yaml).
  std::optional<SensorCalib> calib_override;
  double max_rgb_depth_dt_s = 0.02;  ///< association tolerance without associations.txt
  double max_mask_dt_s = 1e-4;       ///< mask file name vs frame timestamp tolerance
  /// Each frame's IMU samples reach this far beyond its own interval on both sides (s): room for an
  /// online estimate of the camera-IMU offset to cut the interval elsewhere (0: the exact interval).
  double imu_margin_s = 0.0;
  /// Attach and decode the ground-truth masks (masks/): only for diagnostics (the --oracle-masks
  /// ablation, evaluation, tests). Off, masks/ is never opened and frames carry no mask.
  bool read_masks = false;
  /// Read groundtruth.txt at open() (groundTruth()). Off, the file is not opened (a malformed one
  /// cannot stop a run; groundTruthPath() still names it): the SLAM programs read it for their
  /// evaluation after the run.
  bool read_ground_truth = true;
  /// Where the per-frame masks come from: unset = SEQ/masks/ when it exists and read_masks is set; an empty string = no
  /// masks (nothing under SEQ/masks/ is read); a folder = its <timestamp>.png files (e.g. a run's
  /// segmentation/), which must exist.
  std::optional<std::string> masks_dir;
  /// Bags only: the first CameraInfo message's size, intrinsics and distortion replace those of
  /// calib_override (its IMU part and DepthMapFactor stay); a difference is one warning naming
  /// both. Off (a calibration file was given), CameraInfo is only compared, with the same warning.
  bool prefer_camera_info = false;
  /// Where calib_override came from (a calib.yaml, the settings file), for messages.
  std::string calib_override_source;
};

/// Not thread-safe: one consumer calls next().
class SequenceReader {
 public:
  /// Detects the layout and reads the index, calibration, IMU and (unless
  /// SequenceReaderOptions::read_ground_truth is off) the ground truth; throws InputError
  /// (or ConfigError from a bad calib.yaml).
  static SequenceReader open(const std::string& sequence_dir,
                             const SequenceReaderOptions& options = {});
  /// A ROS 1 bag as a sequence (bag_topics.h). Reads the bag's index, the header stamps of the
  /// colour and depth messages (pairs associated by SequenceReaderOptions::max_rgb_depth_dt_s, the
  /// folder reader's rule), the IMU topics whole and the first CameraInfo; images are read and
  /// decoded by load(), one message at a time. Timestamps are the messages' header stamps. The
  /// calibration is options.calib_override, or CameraInfo (prefer_camera_info, or without an
  /// override: then no IMU calibration). Throws InputError naming the bag, the topic, the message
  /// index and the value (a missing topic lists the bag's topics; an unindexed bag gets the
  /// `rosbag reindex` hint). Masks and ground truth are not read from bags.
  static SequenceReader openBag(const std::string& bag_path, const BagTopics& topics,
                                const SequenceReaderOptions& options = {});

  /// Next frame (images loaded now), or nullopt after the last one. Colour images may be 8-bit
  /// BGR, grey or BGRA (the last two converted to BGR with one warning per reader).
  std::optional<RgbdImuFrame> next();
  /// Frame `index` in [0, frameCount()) with its images loaded now; does not move next().
  /// Without colour, color_bgr stays empty (decoding it is most of a frame's cost). Thread-safe:
  /// several threads may load different frames at once (the reader is not changed).
  RgbdImuFrame load(int index, bool with_colour = true) const;
  /// True when opened with openBag (directory() is then the bag file).
  bool isBag() const { return bag_ != nullptr; }
  /// Back to the first frame.
  void rewind() { next_index_ = 0; }
  /// next() continues at frame `index` (in [0, frameCount()]; frameCount(): at the end). The first
  /// frame read then carries the IMU samples since frame index - 1, as it would in order. Throws
  /// InputError naming the sequence for an index out of range.
  void seek(int index);

  int frameCount() const { return static_cast<int>(entries_.size()); }
  double frameTime(int index) const { return entries_.at(index).t_s; }
  const FrameFiles& frameFiles(int index) const { return entries_.at(index); }
  const SensorCalib& calib() const { return calib_; }
  SequenceLayout layout() const { return layout_; }
  const std::string& directory() const { return dir_; }
  bool hasImu() const { return !imu_.empty(); }
  /// The IMU file read (imu.txt, imu0/data.csv or accel.txt), empty when the sequence has none.
  const std::string& imuPath() const { return imu_path_; }
  /// The whole IMU stream (small: seven doubles per sample).
  const ImuSamples& imu() const { return imu_; }
  bool hasGroundTruth() const { return !ground_truth_.empty(); }
  /// T_world_camera from groundtruth.txt; empty when the sequence has none or it was not read.
  const Trajectory& groundTruth() const { return ground_truth_; }
  /// The sequence's groundtruth.txt when it exists (read or not), else empty.
  const std::string& groundTruthPath() const { return ground_truth_path_; }

 private:
  SequenceReader() = default;
  /// The colour image of `files` as CV_8UC3; 8-bit grey and BGRA are converted (warned once).
  cv::Mat loadColorImage(const FrameFiles& files) const;
  /// load() for a bag: images from the messages (bag_reader.cc).
  void loadFolderImages(const FrameFiles& files, bool with_colour, RgbdImuFrame* frame) const;
  void loadBagImages(int index, bool with_colour, RgbdImuFrame* frame) const;

  std::string dir_;
  SequenceLayout layout_ = SequenceLayout::kDataFormat;
  SensorCalib calib_;
  std::vector<FrameFiles> entries_;
  ImuSamples imu_;
  std::string imu_path_;
  Trajectory ground_truth_;
  std::string ground_truth_path_;
  /// load() may run in several threads at once: the warn-once flag is atomic.
  std::shared_ptr<std::atomic<bool>> warned_color_conversion_ = std::make_shared<std::atomic<bool>>(false);
  int next_index_ = 0;
  double imu_margin_s_ = 0.0;
  /// Set for a bag: its index, and the lock its reads take (load() stays thread-safe).
  std::shared_ptr<const detail::BagSource> bag_;
};

}  // namespace ltlo::io
