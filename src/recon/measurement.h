#pragma once
// The per-frame measurement on the fusion grid (input downsampled by Recon.Downsample): vertices,
// normals, colours, radii and radial weights of one RGB-D frame, in the camera frame.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "ltlo/core/camera.h"
#include "ltlo/core/settings.h"
#include "ltlo/recon/surfel_fusion.h"
#include "worker_pool.h"

namespace ltlo::recon {

/// Fusion-grid pixel states.
enum class PixelState : uint8_t {
  kInvalid = 0,  ///< no depth, outside the range, at a depth jump, or no normal
  kGeometry,     ///< valid vertex and normal: evidence of free space, not fused
  kFusable,      ///< also static and seen at an acceptable angle
};

/// Buffers are reused frame after frame (no allocation once sized).
struct Measurement {
  int width = 0;
  int height = 0;
  std::vector<PixelState> state;
  std::vector<float> depth_m;           ///< block mean depth, 0 where the block is not one surface
  std::vector<float> smoothed_depth_m;  ///< edge-aware 5 x 5 mean of depth_m (for normals)
  std::vector<float> scratch_m;
  std::vector<Eigen::Vector3f> point_c;   ///< camera frame, metres
  std::vector<Eigen::Vector3f> normal_c;  ///< unit, towards the camera
  std::vector<Eigen::Vector3f> colour_rgb;
  std::vector<float> radius_m;
  std::vector<float> alpha;  ///< radial confidence weight in (0.25, 1] (constant per pixel)
  std::vector<Eigen::Vector3f> ray_c;  ///< the pixel centre's ray at z = 1 (constant per pixel)
  std::vector<uint8_t> dynamic;        ///< 1 where the grown dynamic mask touches the block

  /// Counts of kGeometry-or-better and kFusable pixels.
  int num_geometry = 0;
  int num_fusable = 0;
};

/// Depth noise sigma(z) = DepthNoise z^2 and the association window AssocDistance + 3 sigma(z).
inline float associationWindowM(const ReconOptions& options, float depth_m) {
  return static_cast<float>(options.assoc_distance_m) +
         3.0f * static_cast<float>(options.depth_noise_m) * depth_m * depth_m;
}

/// The fusion-grid camera: blocks of `downsample` input pixels (a partial last row or column of
/// blocks is dropped), pixel centres kept consistent (u' = (u + 0.5) / s - 0.5).
PinholeCamera fusionCamera(const PinholeCamera& camera, int downsample);

/// Fills `out` from `frame` (sizes asserted against `camera`, the input camera). `fusion_camera`
/// is fusionCamera(camera, options.downsample).
/// Rows are split over `pool`'s threads; pool = nullptr runs everything on the calling thread.
void computeMeasurement(const FusionFrame& frame, const PinholeCamera& camera,
                        const PinholeCamera& fusion_camera, const ReconOptions& options,
                        WorkerPool* pool, Measurement* out);

}  // namespace ltlo::recon
