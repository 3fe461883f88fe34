#pragma once
/// FrameSegmenter: the static/dynamic segmentation step of tracking (DESIGN.md "Tracking &
/// segmentation"). The Tracker owns one and calls it on every frame between the motion prediction
/// and the feature matching; System only creates it from the settings and hands it over.
///
/// Per frame, in the tracking thread:
///   begin(input)            System, before the ORB extraction: starts the work that needs only the
///                           images (depth clustering, pyramids), possibly on a persistent worker
///                           thread, so it overlaps the ORB extraction;
///   segment(frame, prior)   Tracker::track, after the prediction: finishes, sets the frame's
///                           segmentation (Frame::setSegmentation) and may refine the predicted
///                           state (thesis Eq. 59: the dense initial state and segmentation).
/// Every begun frame is segmented (tracked, lost or the first one), so the segmenter always holds
/// what the next frame needs (the previous frame's pyramid, labels, Gamma, state).
///
/// Implementations: AllStaticSegmenter (Seg.Enable = 0: one static cluster, the static core's
/// behaviour) and ClusterOnlySegmenter (Seg.DenseInit = 0: depth clusters, every gamma 1) below;
/// the dense segmenter of thesis Eq. 59-64 and the --oracle-masks ablation elsewhere.
#include <memory>
#include <optional>
#include <vector>

#include "ltlo/core/calib.h"
#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/core/timing.h"
#include "ltlo/core/undistorter.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/map/frame.h"

namespace ltlo::map {
class ByteReader;
class ByteWriter;
}  // namespace ltlo::map

namespace ltlo::tracking {

struct PreparedFrame;
class SegmentationWorker;

/// What tracking knows of the motion from the previous frame to the current one when it segments
/// the current frame: the IMU term of thesis Eq. 59, or its stand-ins before the IMU is
/// initialised and without an IMU.
struct MotionPrior {
  enum class Kind {
    kNone,                  ///< no previous frame (or its state is unknown): no motion information
    kConstantVelocity,      ///< RGB-D only: the last inter-frame camera motion repeated
    kGyroConstantVelocity,  ///< IMU not initialised yet: gyroscope rotation, constant-velocity translation
    kImu,                   ///< IMU initialised: preintegration from the previous frame's state
  };
  Kind kind = Kind::kNone;
  /// previous -> current frame, s
  double dt_s = 0.0;
  /// The previous frame's state (tracked or predicted; the world frame of the active map).
  SE3 T_w_b_prev;
  Vec3 v_w_b_prev = Vec3::Zero();
  imu::ImuBias bias_prev;
  /// Marginal information of the previous state [dphi; drho; dv; db_g; db_a] (the perturbations of
  /// optim/vertices.h) from tracking's pose-inertial optimisation or IMU prediction; absent when
  /// tracking has none (vision only, before the IMU is initialised).
  std::optional<Mat15> prev_information;
  /// The predicted state of the current frame (what the tracker would use without segmentation).
  SE3 T_w_b_pred;
  Vec3 v_w_b_pred = Vec3::Zero();
  /// IMU preintegrated from the previous frame to the current one, linearised at bias_prev
  /// (kImu and kGyroConstantVelocity; null otherwise).
  std::shared_ptr<const imu::Preintegrated> pim;
  /// gravity in the world frame (kImu)
  Vec3 g_w = imu::gravityWorld();
  /// body -> camera extrinsic of the frame (T_b_c)
  SE3 T_b_c;
};

/// What segment() found, beyond the segmentation it set on the frame.
struct SegmentationOutcome {
  /// The state below replaces the prediction as the initial guess of feature tracking.
  bool state_refined = false;
  SE3 T_w_b;
  Vec3 v_w_b = Vec3::Zero();
  imu::ImuBias bias;
  /// share of the pixels with depth in clusters below the static threshold (diagnostics, logs)
  double dynamic_share = 0.0;
};

/// Not thread-safe: one tracking thread calls begin() and segment() alternately.
class FrameSegmenter {
 public:
  virtual ~FrameSegmenter() = default;
  /// Starts segmenting `input` (its images must stay alive until segment() or cancel() returns).
  virtual void begin(const io::RgbdImuFrame& input) = 0;
  /// Finishes the frame begun last: sets frame.setSegmentation(...) and returns the outcome.
  virtual SegmentationOutcome segment(map::Frame& frame, const MotionPrior& prior) = 0;
  /// No segment() follows the last begin() (error path): waits for any work on the images.
  virtual void cancel() {}
  /// The run is over: stops any worker thread of the segmenter (after a pending frame is done);
  /// no begin() follows. Idempotent.
  virtual void finish() {}
  /// Short name for logs and metrics ("all-static", "clusters", "dense", "oracle-masks").
  virtual const char* name() const = 0;

  // ---- a run resumed from an atlas file (system/run_state.h) ----
  /// What the next frame's segmentation reads of the frames before (after the last segment()).
  /// Default: nothing (each frame is segmented on its own).
  virtual void writeState(map::ByteWriter& out) const { (void)out; }
  /// Restores it; throws AtlasFileError (file, section, byte) on a malformed record.
  virtual void readState(map::ByteReader& in) { (void)in; }
  /// After readState: the time (s) of the previous frame whose images restorePreviousFrame needs
  /// (what is rebuilt from them rather than stored: the dense pyramid and clusters), or nullopt
  /// when none is needed.
  virtual std::optional<double> previousFrameTime() const { return std::nullopt; }
  /// Rebuilds the previous frame's image work from its input, as segment() left it; throws
  /// InputError when `previous` is not the frame previousFrameTime() names.
  virtual void restorePreviousFrame(const io::RgbdImuFrame& previous) { (void)previous; }
  /// After readState: the times (s, oldest first) of earlier frames the segmenter keeps whose images
  /// restoreKeptFrame needs, one call each in this order, before restorePreviousFrame (the dense
  /// segmenter's reference frames, Dense.ReferenceBaseline). Default: none.
  virtual std::vector<double> keptFrameTimes() const { return {}; }
  /// Rebuilds the next of them from its input; throws InputError when `frame` is not that frame.
  virtual void restoreKeptFrame(const io::RgbdImuFrame& frame) { (void)frame; }
};

/// Seg.Enable = 0: every frame is one static cluster (the static core's behaviour, for ablations).
class AllStaticSegmenter final : public FrameSegmenter {
 public:
  explicit AllStaticSegmenter(double static_threshold) : static_threshold_(static_threshold) {}
  void begin(const io::RgbdImuFrame&) override {}
  SegmentationOutcome segment(map::Frame& frame, const MotionPrior& prior) override;
  const char* name() const override { return "all-static"; }

 private:
  double static_threshold_;
};

/// Seg.DenseInit = 0: the depth over-segmentation of every frame with all gamma = 1 (local mapping's
/// robust VIBA may still refine them on keyframes). The clustering (segmentation::DepthKMeans at
/// Dense.Resolution) runs on a persistent worker thread between begin() and segment(); `timing`
/// (optional) gets "tracking.segmentation" and "tracking.segmentation_cpu".
class ClusterOnlySegmenter final : public FrameSegmenter {
 public:
  ClusterOnlySegmenter(const SegmentationOptions& segmentation, const DenseOptions& dense, const PinholeCamera& camera,
                       TimingStats* timing = nullptr, std::shared_ptr<const Undistorter> undistorter = nullptr);
  ~ClusterOnlySegmenter() override;
  void begin(const io::RgbdImuFrame& input) override;
  SegmentationOutcome segment(map::Frame& frame, const MotionPrior& prior) override;
  void cancel() override;
  void finish() override;
  const char* name() const override { return "clusters"; }

 private:
  double static_threshold_;
  std::unique_ptr<PreparedFrame> prepared_;
  std::unique_ptr<SegmentationWorker> worker_;  // last: its thread stops before the rest goes
};

}  // namespace ltlo::tracking
