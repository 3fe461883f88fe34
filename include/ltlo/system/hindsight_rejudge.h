#pragma once
/// Hindsight re-judging (Seg.HindsightRejudge, issues 28 and 32): a frame's depth clusters judged again after the run
/// by the Gamma step of Eq. 59-61, at the final poses, where the online motion was wrong.
///
/// Online, the dense step judges each cluster by its Eq. 60 cost under the motion the tracker knew then: the IMU
/// prediction refined by the images, against the previous frame and a reference frame one Dense.ReferenceBaseline back.
/// While tracking is lost behind a mover that motion is dead reckoning on an estimated accelerometer bias; 3 cm off
/// over the 0.3 s baseline misaligns a wall 2 m away by several pixels, and the wall beside the mover is called dynamic
/// (stop 57: ltlo s3 realsense at 11.0-11.5 s). Once the run is over, the final poses (bundle adjusted, loops closed)
/// say how the camera moved, as trajectory.txt corrects trajectory_online.txt.
///
/// The gate: a frame is judged again when its surface, seen from the reference frame, lies more than min_shift_px label
/// pixels (mean over a grid of the frame's depth) from where the online relative pose put it, or when the online poses
/// of the frame and of its reference lie in different maps (a new map began between them). Elsewhere the online
/// judgement stands.
///
/// The judgement: DenseSolver::solve on the frame, its previous frame and its reference frame, prepared as tracking
/// prepares them (tracking/prepared_frame.h: the lens undistorted, the depth K-means), with a relative-pose prior
/// pinned to the final poses (sigma kPinnedSigma) so the state step cannot move and every Gamma step runs at the final
/// motion. The previous frame's scores (the temporal prior of Eq. 54) are its clusters' static shares in its online
/// mask or, when it was judged again just before on the same thread (a stretch, frames in order), the larger of that
/// and its new score per cluster. The reference's brightness relative to the previous frame is fitted first by a solve
/// of the previous frame against the reference at their final poses (auto-exposure steps). The new scores give a mask
/// on the raw image's grid, as the online masks are written, and it can only turn the online mask's dynamic pixels
/// static: a wrong motion misaligns the static room and raises false dynamics, which is what re-judging is for, while a
/// pixel the online motion found consistent was static under it. Judged alone, the final poses call other pixels
/// dynamic where the online pass was right (ltlo s3 realsense, stop 60: the strip of wall beside the far box at 11.6
/// s). The hindsight relabelling (hindsight_masks.h) then runs on the result in place of the online mask.
#include <cstdint>
#include <functional>
#include <memory>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "ltlo/core/camera_model.h"
#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/core/undistorter.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/segmentation/dense_frame.h"
#include "ltlo/segmentation/dense_solver.h"
#include "ltlo/segmentation/depth_kmeans.h"
#include "ltlo/system/segmentation_writer.h"
#include "ltlo/tracking/prepared_frame.h"

namespace ltlo::system {

struct RejudgeOptions {
  bool enable = true;              ///< Seg.HindsightRejudge
  double min_shift_px = 0.5;       ///< Seg.HindsightRejudgeMinShift, label pixels
  double reference_baseline_s = 0.3;  ///< Dense.ReferenceBaseline (0: the previous frame alone)
  double static_threshold = 0.5;   ///< Seg.StaticThreshold
  segmentation::DenseFrameOptions frame;
  segmentation::DenseSolverOptions solver;
  segmentation::DepthKMeansOptions clusters;

  static RejudgeOptions from(const Settings& settings);
};

/// The poses of one frame of the gate: final (null: none in the final map) and online (null: none).
struct RejudgePoses {
  const SE3* T_w_c_final = nullptr;
  const SE3* T_w_c_online = nullptr;
  std::uint64_t online_map = 0;
};

/// One per thread: keeps its solver, clusterer and prepared frames between frames.
class HindsightRejudger {
 public:
  HindsightRejudger(const CameraModel& camera, std::shared_ptr<const Undistorter> undistorter,
                    const RejudgeOptions& options);

  /// Mean shift, label pixels, of the frame's surface (raw depth `depth_m`, CV_32F m) in the reference
  /// frame between the final and the online relative pose; +infinity when the online poses lie in
  /// different maps, -1 when the gate cannot be asked (a pose missing, no depth).
  double onlineShiftPx(const cv::Mat& depth_m, const RejudgePoses& current, const RejudgePoses& reference) const;

  /// Loads frame `index` of the sequence with its colour image and its online mask.
  using FrameLoader = std::function<io::RgbdImuFrame(int index)>;

  /// The frame's mask (CV_8UC1 at the raw size, 255 = dynamic: the online mask in, the result out)
  /// judged again at the final poses of frame `current`, frame `previous` and frame `reference` (< 0:
  /// the previous frame alone), each loaded by `load` unless one of the last kCachedFrames prepared is
  /// that frame (a stretch judged again frame by frame prepares each frame once): a pixel stays dynamic
  /// where both say so. False (mask untouched) when a frame lacks a colour or depth image or clusters.
  bool rejudge(int current, const SE3& T_w_c_current, int previous, const SE3& T_w_c_previous, int reference,
               const SE3& T_w_c_reference, const FrameLoader& load, cv::Mat* mask);

  /// Frames kept prepared: the previous frame and the reference baseline's frames of a stretch.
  static constexpr std::size_t kCachedFrames = 16;
  /// Sigma of the relative-pose prior that pins the state to the final poses, rad and m.
  static constexpr double kPinnedSigma = 1e-5;
  /// Pixel step of the gate's grid on the raw depth.
  static constexpr int kGateStride = 8;

 private:
  /// A prepared frame and its clusters' static shares in its online mask (the temporal prior of Eq. 54
  /// when it is the previous frame).
  struct CachedFrame {
    int index = -1;
    tracking::PreparedFrame prepared;
    std::vector<double> static_shares;
    bool valid = false;
  };
  /// Frame `index`, prepared (from the cache, else loaded and prepared into the oldest entry).
  const CachedFrame& prepared(int index, const FrameLoader& load);
  /// The static share of each cluster of `prepared` in `mask` (raw grid, 255 = dynamic).
  std::vector<double> staticShares(const tracking::PreparedFrame& prepared, const cv::Mat& mask);

  CameraModel camera_;
  std::shared_ptr<const Undistorter> undistorter_;
  RejudgeOptions options_;
  PinholeCamera label_camera_;
  int label_scale_ = 1;
  segmentation::DenseSolver solver_;
  segmentation::DepthKMeans kmeans_;
  std::vector<std::unique_ptr<CachedFrame>> cache_;  ///< most recently used first
  RawGridMasks raw_grid_;
  cv::Mat mask_ideal_, rejudged_;
  std::vector<std::pair<int, int>> gate_pixels_;  ///< (u, v) of the gate's grid, raw image
  std::vector<Vec3> gate_bearings_;               ///< their rays, z = 1 (zero: outside the lens model)
};

}  // namespace ltlo::system
