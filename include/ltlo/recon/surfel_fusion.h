#pragma once
/// SurfelFusion: fuses registered RGB-D frames with known camera poses into a surfel model of the
/// static background (ElasticFusion-style; Keller et al. 2013 "Real-time 3D reconstruction in
/// dynamic scenes using point-based fusion", Whelan et al. 2015 "ElasticFusion").
///
/// Per frame (integrate()):
///   1. measurement: depth and colour averaged over Recon.Downsample blocks (the fusion grid),
///      vertex map, normal map (central differences of an edge-aware 5 x 5 smoothing of the depth,
///      two pixels apart, one where a structure is thinner), radius r = (sqrt 2 / 2) (z / f) /
///      cos(theta)
///      from depth and viewing angle, radial weight alpha = exp(-gamma^2 / (2 * 0.6^2)) with gamma
///      the pixel's distance from the principal point over the centre-to-corner distance;
///   2. the model is rendered at the frame's pose into an index map twice as fine as the fusion
///      grid (surfel centres, nearest wins; cells outside the frustum are culled);
///   3. projective data association: a fusion pixel looks at the 2 x 2 index-map pixels it covers
///      and takes the most confident surfel within AssocDistance + 3 sigma(z) of its tangent plane
///      and AssocMaxAngle of its normal; an index-map pixel belongs to one fusion pixel, so a
///      surfel takes at most one measurement per frame;
///   4. update (Keller et al. 2013, section 4.2): confidence-weighted averages of position, normal,
///      colour and radius, unless the measurement is much coarser (r > 1.5 r_surfel), which only
///      adds confidence; confidence += alpha. Unassociated static pixels become new surfels;
///   5. free space: a rendered surfel lying in front of the measured surface at its pixel (beyond
///      the association window, along the measured normal and the ray) is a violation; unstable
///      surfels go at once, stable ones after Recon.FreeSpaceVotes net violations;
///   6. unstable surfels (confidence < Recon.ConfidenceStable) older than Recon.UnstableTime go.
///
/// Only pixels whose dynamic mask is 0 (after growing it by Recon.MaskDilation) are fused; every
/// pixel with depth counts as evidence of free space.
///
/// Not thread-safe: one thread calls integrate() (which splits its loops over `threads` - 1 worker
/// threads of its own and the caller). Offline: no SLAM threads, no map locks.
#include <memory>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "ltlo/core/camera.h"
#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/core/timing.h"
#include "ltlo/recon/surfel.h"

namespace ltlo::recon {

/// One RGB-D frame to fuse.
struct FusionFrame {
  double t_s = 0.0;
  SE3 T_w_c;             ///< camera pose in the world
  cv::Mat depth_m;       ///< CV_32F metres, 0 = no reading; the camera's size
  cv::Mat colour_bgr;    ///< CV_8UC3, same size
  cv::Mat dynamic_mask;  ///< CV_8UC1, 255 = dynamic (not fused); empty = every pixel static
};

struct Measurement;  // src/recon/measurement.h

/// A frame's measurement on the fusion grid (vertices, normals, radii, which pixels fuse), made by
/// SurfelFusion::prepare(). It does not depend on the model, so loader threads can prepare the
/// next frames while one thread fuses an earlier one. Preparing the same object again reuses its
/// buffers.
class PreparedFrame {
 public:
  PreparedFrame();
  ~PreparedFrame();
  PreparedFrame(PreparedFrame&&) noexcept;
  PreparedFrame& operator=(PreparedFrame&&) noexcept;

 private:
  friend class SurfelFusion;
  std::unique_ptr<Measurement> measurement_;
};

/// What one integrate() call did.
struct FusionFrameStats {
  int measured_pixels = 0;  ///< fusion pixels with valid depth and normal
  int fused_pixels = 0;     ///< of those, static and seen at an acceptable angle
  int merged = 0;           ///< fused into an existing surfel
  int created = 0;          ///< new surfels
  int covered = 0;          ///< dropped: inside a disc that took a measurement this frame
  int rendered = 0;         ///< model surfels in the index map
  int removed_unstable = 0;
  int removed_free_space = 0;
};

/// Totals over the whole run.
struct FusionTotals {
  long frames = 0;
  long merged = 0;
  long created = 0;
  long removed_unstable = 0;
  long removed_free_space = 0;
};

class SurfelFusion {
 public:
  /// `camera`: the input images' intrinsics and size. Options are validated (ConfigError).
  /// `threads` (1-16) split each frame's stages; the result does not depend on it.
  SurfelFusion(const PinholeCamera& camera, const ReconOptions& options, int threads = 1);
  ~SurfelFusion();
  SurfelFusion(const SurfelFusion&) = delete;
  SurfelFusion& operator=(const SurfelFusion&) = delete;

  /// Fuses one frame; frames come in time order. Sizes must match the camera (asserted).
  FusionFrameStats integrate(const FusionFrame& frame);
  /// Measures `frame` into `out` (step 1 above) on the calling thread alone. Const and
  /// thread-safe: any number of threads may prepare frames while one thread integrates.
  void prepare(const FusionFrame& frame, PreparedFrame* out) const;
  /// Fuses `frame` measured by prepare(); the result is that of integrate(frame).
  FusionFrameStats integrate(const FusionFrame& frame, const PreparedFrame& prepared);

  /// Surfels with confidence >= Recon.ConfidenceStable, in no particular order.
  std::vector<Surfel> stableSurfels() const;
  /// Every surfel of the model, stable or not.
  std::vector<Surfel> allSurfels() const;
  std::size_t numSurfels() const;
  const FusionTotals& totals() const;
  /// Heap bytes held by the model (surfel storage and cells), for the memory report.
  std::size_t modelBytes() const;
  /// Time per stage and frame: recon.measurement (integrate(frame) only), recon.index_map,
  /// recon.associate_fuse, recon.free_space, recon.clean_insert.
  const TimingStats& timing() const;

 private:
  FusionFrameStats fuseMeasured(const FusionFrame& frame, const Measurement& measurement);

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ltlo::recon
