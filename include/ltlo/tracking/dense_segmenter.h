#pragma once
/// DenseSegmenter (Seg.Enable = 1, Seg.DenseInit = 1): the dense initial state and segmentation of
/// thesis Eq. 59-64 on every frame, as a FrameSegmenter step of tracking.
///
///   begin(input)          the persistent worker thread builds the frame's intensity + depth pyramid
///                         (DenseFrame, Dense.*) and clusters its base level (DepthKMeans, Seg.*)
///                         while the tracking thread extracts ORB features;
///   segment(frame, prior) the tracking thread waits for it and solves Eq. 59 against the previous
///                         frame (segmentation::DenseSolver) with the motion prior turned into the
///                         IMU term (kImu), the gyroscope rotation + constant-velocity prior
///                         (kGyroConstantVelocity, before the IMU is initialised) or the
///                         constant-velocity prior (kConstantVelocity, RGB-D only); it sets the
///                         frame's segmentation and returns the refined state.
/// Every segmented frame (tracked or not) becomes the previous frame of the next one: its pyramid,
/// labels and Gamma are kept. Without a previous frame (the first one, or after a frame without
/// images) every cluster is static.
///
/// Reference frames (Dense.ReferenceBaseline = B > 0, segmentation::DenseReference): while the
/// motion prior is the IMU term, a frame every B / 2 s is kept once the next frame's prior gives its
/// tracked pose (its PreparedFrame moves out of the two working slots into a small ring; the ring's
/// oldest goes back as the spare, so nothing is copied or allocated once the ring is full). Each
/// solve takes the newest kept frame at least B old. The kept poses follow the world corrections the
/// IMU prior applies to the previous pose; a correction of more than kReferenceJumpM /
/// kReferenceJumpRad (a loop or a merge moved the map), a prior without the IMU term or a frame
/// without images clears the ring.
#include <memory>
#include <string>
#include <vector>

#include "ltlo/core/settings.h"
#include "ltlo/core/timing.h"
#include "ltlo/segmentation/dense_solver.h"
#include "ltlo/tracking/frame_segmenter.h"

namespace ltlo::tracking {

struct PreparedFrame;
class SegmentationWorker;

/// The DensePrior of a motion prior: kImu -> the IMU term, its previous state recovered from the
/// prediction and the preintegration (imu::predict inverted), so that a prediction from a keyframe
/// local mapping moved since the previous frame keeps the frame-to-frame motion;
/// kGyroConstantVelocity -> a pose prior with the gyroscope rotation and the predicted
/// (constant-velocity) camera position; kConstantVelocity -> a pose prior at the prediction; kNone -> a weak pose prior at the
/// prediction (image alignment alone). Standard deviations from Dense.Prior*.
segmentation::DensePrior densePrior(const MotionPrior& prior, const DenseOptions& dense);

/// Not thread-safe: one tracking thread calls begin() / segment() alternately (the worker thread
/// is internal).
class DenseSegmenter final : public FrameSegmenter {
 public:
  /// `camera` is the input camera (its size a multiple of Dense.Resolution); `timing` (optional,
  /// must outlive the segmenter) gets "tracking.segmentation" (pyramid + clustering, worker) and
  /// "tracking.dense" (the solve), wall and thread CPU time ("..._cpu").
  DenseSegmenter(const SegmentationOptions& segmentation, const DenseOptions& dense,
                 const LocalMappingOptions& local_mapping, const PinholeCamera& camera,
                 TimingStats* timing = nullptr, std::shared_ptr<const Undistorter> undistorter = nullptr);
  ~DenseSegmenter() override;

  void begin(const io::RgbdImuFrame& input) override;
  SegmentationOutcome segment(map::Frame& frame, const MotionPrior& prior) override;
  void cancel() override;
  void finish() override;
  const char* name() const override { return "dense"; }
  /// Whether a previous frame is held, its time and scores Gamma; its pyramid and clusters are
  /// rebuilt from its images (restorePreviousFrame: the same DenseFrame and DepthKMeans code, the
  /// same result bit for bit), a few hundred kB per frame not stored.
  void writeState(map::ByteWriter& out) const override;
  void readState(map::ByteReader& in) override;
  std::optional<double> previousFrameTime() const override { return previous_pending_; }
  void restorePreviousFrame(const io::RgbdImuFrame& previous) override;
  /// The kept frames (Dense.ReferenceBaseline) are rebuilt from their images too, before the
  /// previous frame; their poses and brightness come from the state.
  std::vector<double> keptFrameTimes() const override;
  void restoreKeptFrame(const io::RgbdImuFrame& frame) override;

  /// The last solve (diagnostics, tests); empty gamma before the second frame.
  const segmentation::DenseResult& lastResult() const { return last_result_; }

 private:
  SegmentationOptions segmentation_;
  DenseOptions dense_;
  PinholeCamera camera_;
  TimingStats* timing_;
  std::shared_ptr<const Undistorter> undistorter_;  // null or inactive: the images are ideal already
  std::unique_ptr<PreparedFrame> frames_[2];  // [current_] is being prepared / segmented
  int current_ = 0;

  /// A kept frame (Dense.ReferenceBaseline).
  struct KeptFrame {
    std::unique_ptr<PreparedFrame> frame;
    /// its body pose in the world of the last prior
    SE3 T_w_b;
    /// brightness from it to the previous frame: I_kept ~ gain I_prev + offset
    double gain = 1.0;
    double offset = 0.0;
  };
  /// Updates the kept frames before a solve: drops them without the IMU term or on a large world
  /// correction, else carries them by the correction; the previous frame is kept when it was marked.
  void updateKeptFrames(const MotionPrior& prior, const segmentation::DensePrior& dense_prior);
  /// After a solve: the kept frames' brightness carried to the current frame, and whether the
  /// current frame is to be kept.
  void afterSolve(const MotionPrior& prior, double t_s);
  /// The newest kept frame at least Dense.ReferenceBaseline older than `t_s` (nullptr: none).
  const KeptFrame* referenceFor(double t_s) const;
  void clearKeptFrames();
  /// Debug log: what the reference changed.
  std::string referenceSummary() const;
  std::vector<KeptFrame> kept_;  ///< oldest first
  std::vector<std::unique_ptr<PreparedFrame>> spare_frames_;
  bool keep_previous_ = false;  ///< the previous frame is to be kept once its pose is known
  /// Restored kept frames whose images restoreKeptFrame has not had yet (from kept_.size() on).
  struct PendingKept {
    double t_s = 0.0;
    SE3 T_w_b;
    double gain = 1.0;
    double offset = 0.0;
  };
  std::vector<PendingKept> pending_kept_;
  bool has_previous_ = false;
  std::vector<double> previous_gamma_;
  double previous_t_s_ = 0.0;  ///< time of the previous frame (when has_previous_)
  /// Restored with a previous frame whose images restorePreviousFrame has not had yet: its time.
  std::optional<double> previous_pending_;
  segmentation::DenseSolver solver_;
  segmentation::DenseResult last_result_;
  std::unique_ptr<SegmentationWorker> worker_;  // last: its thread stops before the rest goes
};

}  // namespace ltlo::tracking
