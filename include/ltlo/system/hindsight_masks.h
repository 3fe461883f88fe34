#pragma once
/// Hindsight masks (RUN/segmentation_final/): every frame's mask relabelled once the run is over, against
/// the final static map and the final poses (issue 32). trajectory.txt is to trajectory_online.txt what
/// segmentation_final/ is to segmentation/.
///
/// Online, a box that stands still in front of a part of the room the map has not seen yet looks like
/// the room: a robot and a box both at rest, or a box in view from the first frame. Nothing that moves
/// can be seen until it moves. Once it has moved, the room behind it enters the map, and the frames
/// before can be judged with what the map knows now. The test is Eq. 56's, with the final map: a
/// static point behind a frame's surface says that surface stood in front of the static world,
///
///   gamma~_c = 1 - sum_j beta_j v_j / sum_j beta_j
///
/// over the static map points j (beta >= min_beta) projecting into region c of the frame, with v_j = 1
/// when the point lies behind the frame's surface by more than depth noise (the depth-gap tolerance of
/// the clusters' V_i) and 0 when at the surface. Online, Eq. 56 grades the vote with the distance
/// (min(1, lambda_p d_j)) because the map is still a guess; here the free-space test below decides.
/// Regions are the depth-continuous pieces of the frame's depth clusters (the same depth K-means as
/// online, at the label resolution, each cluster split where neighbouring depths jump by more than the
/// V_i threshold, so a cluster holding a box's edge and the wall beside it is judged piece by piece).
/// A region the online mask calls static (most of its pixels) turns dynamic when at least min_points
/// points vote there and gamma~_c < static_threshold (Seg.StaticThreshold). With to_static, a region
/// it calls dynamic turns static when at least min_points vote and gamma~_c >= static_share: nearly all
/// the static points there lie on its surface, none behind (a strip of wall that shared a depth cluster
/// with a box online, and is a region of its own here). Of a flipped region's pixels, those whose
/// nearest voter (3-D) lies within vote_radius_m and votes the new label change (a box's side face and
/// the floor it stands on meet without a depth step: the votes on the face do not speak for the far end
/// of the floor). Two rules keep static structure static:
///   - a point behind the frame's surface votes only when that surface point lies in space a keyframe
///     saw through: within ray_tolerance_m of the segment from the centre of a keyframe that observed
///     the point to the point. A wall point hidden by parallax behind a static cupboard, seen past the
///     cupboard's edge from elsewhere, says nothing about the cupboard;
///   - a point in front of the frame's surface does not vote: the frame sees past it, which speaks
///     against the point, not for or against the surface.
/// Free space (free_space): the same question asked of the keyframes' depth images instead of the map's
/// points. A surface point of the frame that at least free_space_views keyframes saw through (their
/// depth along the ray through it lies beyond it by more than the V_i gap) stood where the room was seen
/// empty: whatever is there moved. It needs no texture and no point behind it (a plain box at rest, the
/// floor behind a box seen at a grazing angle), and a static surface is never seen through. Samples every
/// kFreeSpaceStride label pixels; a region the online mask calls static with at least min_points seen-
/// through samples turns dynamic, pixel by pixel as its nearest sample (3-D, among the region's samples
/// some keyframe saw) says. The keyframe's depth is the nearest of blocks of 2 x 2 label pixels, then of
/// the 3 x 3 blocks around (unknown beside a hole), so a depth edge counts as the surface in front and a
/// pose error of a few pixels does not see past it.
/// The same samples veto to_static: a region the online mask calls dynamic with at least min_points
/// seen-through samples stays dynamic, whatever points lie on its surface (points made on a box while it
/// stood there and never seen again keep the beta of their first keyframes).
/// A frame asks at most free_space_max_views keyframes: when more face it, those that saw most of
/// kFreeSpaceProbes samples of its surface (seen through counting twice). So the pass's cost per frame is
/// bounded, not the run's keyframes (revisits add views of the same walls).
/// With free_space_frame_interval_s, a frame every that many seconds (not a keyframe's) is a view as well: a
/// door leaf at rest where only frames between the keyframes saw the doorway empty. A frame asks no frame
/// view within kFrameViewMinGapS of its own time.
/// A view sees through a surface point when its depth there lies beyond the point by more than
/// free_space_tolerance_m + 3 sigma of the sensor's depth noise (depth_noise_m z^2), at most the clusters'
/// gap (0: the gap). The gap joins the pieces of one surface across noise and slant (0.15 m from 1.6 m on),
/// and a view that saw the wall where a closed door leaf stands 6 cm in front of it did not see through
/// the leaf. The map points' votes keep the gap (a point 6-15 cm behind the surface counts as on it):
/// judged with the tolerance as well, 24 of 27 runs moved by 0.0001 either way. The folder pass measures
/// the noise in kNoiseSampleFrames of the run's depth images first (measureDepthNoise), and the larger of
/// it and depth_noise_m counts: a sensor noisier than Recon.DepthNoise says does not see through walls.
/// Frames without a final pose in the map the points belong to keep their online mask.
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "ltlo/core/camera_model.h"
#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/map/ids.h"
#include "ltlo/segmentation/depth_kmeans.h"
#include "ltlo/system/hindsight_rejudge.h"
#include "ltlo/system/run_records.h"

namespace ltlo::system {

struct HindsightMaskOptions {
  /// K, Lloyd iterations and neighbour gap of the depth clusters (Seg.*)
  segmentation::DepthKMeansOptions clusters;
  /// label resolution (Dense.Resolution), the camera's divided by an integer
  int label_width = 320;
  int label_height = 240;
  double static_threshold = 0.5;   ///< gamma~ below this is dynamic (Seg.StaticThreshold)
  double min_beta = 0.5;           ///< static map points (LocalMapping.MinPointBeta)
  int min_points = 3;              ///< votes a cluster needs (Seg.HindsightMinPoints)
  double ray_tolerance_m = 0.05;   ///< Seg.HindsightRayTolerance
  double vote_radius_m = 0.3;      ///< Seg.HindsightVoteRadius
  bool to_static = true;           ///< dynamic -> static too (Seg.HindsightToStatic)
  double static_share = 0.9;       ///< gamma~ at least this turns dynamic -> static (Seg.HindsightStaticShare)
  bool free_space = true;          ///< the keyframes' depth as free space (Seg.HindsightFreeSpace)
  int free_space_views = 2;        ///< keyframes that must see through a sample (Seg.HindsightFreeSpaceViews)
  /// keyframes a frame asks at most (Seg.HindsightFreeSpaceMaxViews, 0 = all): when more face it, those
  /// that saw most of kFreeSpaceProbes probes of its surface (seen through counting twice)
  int free_space_max_views = 32;
  /// frames that are not keyframes also serve as views, one per this many seconds of each stretch of
  /// final poses (Seg.HindsightFreeSpaceFrameInterval; 0: keyframes only), at most kMaxFrameViews of
  /// them over the run (the interval widens on longer runs)
  double free_space_frame_interval_s = 0.0;
  /// seen through: beyond the surface by free_space_tolerance_m + 3 depth_noise_m z^2, at most the
  /// clusters' gap (Seg.HindsightFreeSpaceTolerance, Recon.DepthNoise at 1 m; 0: the gap)
  double free_space_tolerance_m = 0.02;
  double depth_noise_m = 0.0025;
  /// The depth noise the folder pass measured in the run's own depth images (measureDepthNoise), m at 1 m;
  /// the tolerance's noise term is 3 x the larger of it and depth_noise_m (0: not measured)
  double measured_noise_m = 0.0;
  int num_threads = 2;             ///< frames relabelled in parallel (folder pass)
  /// the frames whose online motion was wrong judged again at the final poses first (folder pass with
  /// the online trajectory; hindsight_rejudge.h)
  RejudgeOptions rejudge;

  static HindsightMaskOptions from(const Settings& settings);
};

/// What one frame's relabelling found.
struct HindsightFrameResult {
  int clusters = 0;         ///< depth clusters of the frame
  int regions = 0;          ///< their depth-continuous pieces
  int regions_voted = 0;    ///< regions with at least min_points votes
  int regions_flipped = 0;  ///< static online, dynamic in hindsight
  int regions_to_static = 0;  ///< dynamic online, static in hindsight
  int regions_free_space = 0;  ///< of regions_flipped, those flipped by free space
  int views_asked = 0;         ///< keyframe depths the free-space test asked
};

/// A keyframe's depth image as free-space evidence: depth_m at twice the label step (the camera's
/// divided by view_scale), each pixel the nearest depth of its block and of the 3 x 3 blocks around,
/// 0 = unknown (no depth there or beside).
struct FreeSpaceView {
  double t_s = 0.0;
  Mat3 R_c_w = Mat3::Identity();  ///< T_c_w as a matrix and a translation (the inner loop's form)
  Vec3 t_c_w = Vec3::Zero();
  Vec3 axis_w = Vec3::UnitZ();  ///< optical axis in the world
  int view_scale = 4;           ///< camera pixels per view pixel
  bool keyframe = true;         ///< a keyframe's depth; false: a frame's between them (frame interval)
  cv::Mat depth_m;              ///< CV_32F

  /// From a raw depth image (CV_32F m, 0 = none) at the camera's size seen from T_w_c.
  static FreeSpaceView fromDepth(const cv::Mat& depth_m, const SE3& T_w_c, double t_s, int view_scale);
};

/// The per-frame step; one per thread (it keeps its buffers between frames).
class HindsightRelabeller {
 public:
  /// `camera`: the raw camera (lens included) whose images the masks and depths are.
  HindsightRelabeller(const CameraModel& camera, const HindsightMaskOptions& options);

  /// Relabels `mask` (CV_8UC1 at the camera's size, 255 = dynamic; changed in place) of the frame with
  /// raw depth `depth_m` (CV_32F m, 0 = none) seen from T_w_c, with `points` (those with beta >=
  /// min_beta vote; a point behind the surface needs its observer centres).
  /// `views`: the keyframes' depths for the free-space test (empty or options.free_space off: none);
  /// a view at the frame's own time t_s is skipped.
  HindsightFrameResult relabel(const cv::Mat& depth_m, const SE3& T_w_c, const std::vector<MapPointRecord>& points,
                               cv::Mat* mask, const std::vector<FreeSpaceView>& views = {}, double t_s = -1.0);

  /// Label pixels between free-space samples (both directions).
  static constexpr int kFreeSpaceStride = 4;
  /// Samples of the frame's surface that rank the views when more than free_space_max_views face it.
  static constexpr int kFreeSpaceProbes = 64;
  /// A frame view this close in time to the frame is not asked, s: it saw the world as the frame does
  /// (an object at rest stands where it stands), and its neighbours would fill the bound on views.
  static constexpr double kFrameViewMinGapS = 1.0;

 private:
  /// A view's depth beyond a point at depth z_m by more than this saw through it (m); `gap_m` is the
  /// clusters' gap at z_m, which the caller has at hand.
  double freeSpaceTolerance(double z_m, double gap_m) const;
  /// The 3-D point (camera frame) of label pixel (c, r) at its label depth (the pinhole's rays).
  Vec3 backProject(int c, int r) const;
  /// The raw pixel of camera-frame point p_c, or nullopt when p_c lies outside the raw image's field
  /// (its normalised coordinates beyond those of the image's border): a lens polynomial folds points
  /// far outside the field back into the image.
  std::optional<Vec2> projectInField(const Vec3& p_c) const;
  /// x_w lies within ray_tolerance_m of a segment from an observer's centre to the point.
  bool seenThrough(const Vec3& x_w, const MapPointRecord& point) const;
  /// regions_ = the 4-connected pieces of each cluster whose neighbouring depths differ by less than
  /// the clusters' gap threshold; -1 without depth. Returns their number.
  int splitClusters();
  /// Free-space samples of the frame (every region, whatever the online mask says) against `views`;
  /// returns each region's seen-through samples in fs_violated_.
  void sampleFreeSpace(const SE3& T_w_c, const std::vector<FreeSpaceView>& views, double t_s, int num_regions);
  /// active_views_ = the views facing the frame (not its own time); when more than free_space_max_views,
  /// the free_space_max_views that saw most of kFreeSpaceProbes of samples_ (seen through counting
  /// twice; ties to the earlier view), so a frame's cost does not grow with the run's keyframes.
  void selectViews(const SE3& T_w_c, const std::vector<FreeSpaceView>& views, double t_s);
  /// What `view` saw at world point x_w: -1 nothing (out of its field, no depth, or a surface in front),
  /// 0 the point's surface (or behind it within the gap), 1 past it (free space).
  int viewState(const FreeSpaceView& view, const Vec3& x_w) const;
  /// The nearest (3-D) free-space sample of label pixel (c, r) in `region` that some view saw: seen
  /// through (1), seen at or behind (0), none (-1).
  int nearestSampleState(int c, int r, int region, const Vec3& x_c) const;

  CameraModel camera_;
  PinholeCamera label_camera_;
  HindsightMaskOptions options_;
  int scale_ = 1;
  segmentation::DepthKMeans kmeans_;
  cv::Mat label_depth_m_;
  segmentation::DepthClusters clusters_;
  std::vector<double> vote_sum_, beta_sum_;
  std::vector<int> votes_, pixels_, dynamic_pixels_;
  std::vector<char> flip_;
  cv::Mat regions_;          // CV_32S at the label resolution
  struct Voter {
    int region = 0;
    Vec3 x_c;                // the frame's surface point where the point projects
    bool dynamic = false;    // behind the surface (v_j = 1)
  };
  std::vector<Voter> voters_;
  std::vector<int> stack_;   // flood fill
  // Free space: label-pixel bearings (z = 1, lens included), the sample grid's states (-1 unseen, 0
  // seen, 1 seen through) and points (camera frame), the seen-through samples per region, and which
  // flipped regions free space flipped.
  std::vector<Vec2> bearings_;
  Vec2 field_min_ = Vec2::Zero(), field_max_ = Vec2::Zero();  // normalised bounds of the raw image
  int grid_cols_ = 0, grid_rows_ = 0;
  std::vector<signed char> sample_state_;
  std::vector<Vec3> sample_x_c_;
  std::vector<int> fs_violated_;
  std::vector<char> fs_flip_;
  std::vector<const FreeSpaceView*> active_views_;  // this frame's views
  struct FreeSpaceSample {
    int cell = 0;    // index into the sample grid
    int region = 0;
    Vec3 x_c, x_w;   // the frame's surface point, camera frame and world
  };
  std::vector<FreeSpaceSample> samples_;            // this frame's samples, in raster order
  std::vector<std::pair<int, int>> view_scores_;    // view ranking: (-score, index into active_views_)
  std::vector<const FreeSpaceView*> ranked_views_;
};

/// Frame views at most, so the pass's memory stays bounded on hour-long runs (77 KB a VGA view: 150 MB).
constexpr int kMaxFrameViews = 2000;
/// Frames (evenly spread over the run) whose depth measures the sensor's noise (measureDepthNoise).
constexpr int kNoiseSampleFrames = 32;

/// The depth noise of raw depth images (CV_32F m, 0 = none) as sigma(z) = k z^2, k in m at 1 m: on any
/// plane the inverse depth is linear along an image row, so its second difference across three valid
/// neighbours, 1/z0 - 2/z1 + 1/z2, is noise alone, of sigma k sqrt(6). k = 1.4826 MAD / sqrt(6) over every
/// such triple (each second row) whose depths step by less than `clusters`' gap (edges are the MAD's
/// outliers). Spatially correlated noise (stereo sensors) reads lower than it is: the measure can only
/// raise the configured Recon.DepthNoise. 0 without triples.
double measureDepthNoise(const std::vector<cv::Mat>& depths_m, const segmentation::DepthKMeansOptions& clusters);

struct HindsightMaskResult {
  int frames_written = 0;
  int frames_relabelled = 0;   ///< frames with a final pose in the points' map
  int frames_changed = 0;      ///< of those, frames with at least one cluster flipped
  long regions_flipped = 0;
  long regions_to_static = 0;
  long regions_free_space = 0;
  long views_asked = 0;       ///< over the frames (their mean: views_asked / frames_relabelled)
  long regions_voted = 0;
  int free_space_views = 0;   ///< keyframes whose depth served as free space
  int free_space_frame_views = 0;  ///< frames between them whose depth served too
  double measured_noise_m = 0.0;   ///< measureDepthNoise over kNoiseSampleFrames frames (0: not measured)
  long voting_points = 0;     ///< static points (beta >= min_beta)
  int frames_rejudged = 0;    ///< frames judged again at the final poses (hindsight_rejudge.h)
  double rejudge_seconds = 0.0;  ///< thread time of that, summed over the threads
  double seconds = 0.0;
};

/// The folder pass: for every frame of `reader` (opened with masks_dir = the run's segmentation/) that
/// has an online mask, writes <its name> to `out_dir` (created): the online mask relabelled when
/// `trajectory` has the frame's time in `points_map`, else as it is; the `keyframes` of points_map give
/// the free-space views (their depth read from `reader`), with a frame of `trajectory` in points_map every
/// options.free_space_frame_interval_s. Frames are shared among
/// options.num_threads threads (each frame's reading, relabelling and PNG writing on one). With
/// `trajectory_online` (the poses tracking returned) and options.rejudge.enable, a frame whose online
/// motion over the reference baseline the final poses contradict is judged again first
/// (hindsight_rejudge.h; the reader must then give colour images). Throws InputError naming the file
/// when a frame cannot be read or a mask written (after joining).
HindsightMaskResult writeHindsightMasks(const io::SequenceReader& reader, const std::vector<FramePose>& trajectory,
                                        const std::vector<KeyFrameRecord>& keyframes, map::MapId points_map, const std::vector<MapPointRecord>& points,
                                        const CameraModel& camera, const HindsightMaskOptions& options,
                                        const std::string& out_dir, const std::vector<FramePose>& trajectory_online = {});

}  // namespace ltlo::system
