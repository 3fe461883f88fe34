#pragma once
// Per-pixel kernels of the dense initial state and segmentation (thesis Eq. 60-64): warping the
// current frame's pixels into the previous frame (Eq. 63), the intensity and depth residuals
// (Eq. 61-62) with the weights of Eq. 64 and the Cauchy penalty, accumulated into the normal
// equations of the camera motion or into per-cluster evidence. Compiled at -O3: the accumulation
// is written over fixed-width lanes so the compiler vectorises it.
#include <cstdint>
#include <limits>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/segmentation/dense_frame.h"

namespace ltlo::segmentation::detail {

/// T_prev_cur (the current camera in the previous camera's frame) as floats.
struct Warp {
  float R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};  ///< row-major R_prev_cur
  float t[3] = {0, 0, 0};                    ///< t_prev_cur, m
};

/// Robust residual settings shared by both passes.
struct ResidualParams {
  float alpha_intensity = 0.15f;  ///< alpha_I of Eq. 60
  float cauchy_c = 0.5f;          ///< c of the Cauchy penalty F
  /// A pixel whose warped point lies more than this behind the previous depth, m, was hidden in
  /// the previous frame (disoccluded since, e.g. behind a box moving aside): it has no
  /// correspondence and gives neither residuals nor evidence nor prior.
  float occlusion_gap_m = 0.1f;
};

/// Affine brightness change between the two frames (auto-exposure, issue 28): the previous frame's
/// intensity at the warped point is predicted from the current frame's,
///   I_{i-1}(W(u, T)) ~ gain I_i(u) + offset,
/// so the intensity residual of Eq. 61 becomes r_I = I_{i-1}(W(u, T)) - (gain I_i(u) + offset).
/// gain is the previous exposure over the current one (0.8 after a +25 % step), offset in
/// intensity units ([0, 1]). In this direction the residual's derivative by the warp (the
/// previous frame's gradient) does not change, and the fit regresses samples on the current
/// frame's fixed intensities. (DSO writes the mirror, the target predicted from the reference.)
struct Brightness {
  float gain = 1.0f;
  float offset = 0.0f;
};

/// Side of the square blocks of the brightness fit, px of the level.
constexpr int kBrightnessBlockPx = 8;

/// Per-block statistics of the brightness fit ("affine brightness fit", dense_solver.cc): the
/// current level's image cut into blocks of kBrightnessBlockPx; per block b, over its
/// correspondences u with weight w_u (the pixel's score, 0 where either intensity is clipped: a
/// saturated pixel does not follow the affine model), centred current intensities
/// x_u = I_i(u) - 1/2 and samples s_u = I_{i-1}(W(u, T)):
///   w[b] = sum w_u, x[b] = sum w_u x_u, s[b] = sum w_u s_u.
/// The fit compares block means, not pixels: a bilinear sample at a fractional position is a local
/// average, which flattens a texture's peaks and troughs, so a pixel-wise regression of s on I
/// reads every textured pair as a gain below 1 (0.94 on the test room with no change at all),
/// while a block's mean keeps the mean of what it covers.
struct BrightnessBlocks {
  std::vector<double> w, x, s;
  int blocks_per_row = 0;
  /// Zeroes the blocks of a level of `camera`'s size (reuses the buffers).
  void reset(const LevelCamera& camera);
  int blockOf(int pixel, int width) const {
    return (pixel / width) / kBrightnessBlockPx * blocks_per_row + (pixel % width) / kBrightnessBlockPx;
  }
};

/// Gauss-Newton normal equations of the image term of Eq. 60 in the right perturbation eps =
/// [phi; rho] of the current camera pose (T_w_c <- T_w_c Exp(eps)), Cauchy IRLS weights:
///   H = sum gamma w J^T J, b = sum gamma w J^T r.
/// (The cost itself is not needed by the state step: the Gamma step has its own pass.)
struct ImageNormalEquations {
  Mat6 H = Mat6::Zero();
  Vec6 b = Vec6::Zero();
  int num_residuals = 0;
};

/// Buffers (structure of arrays) reused between calls: the warped and sampled pixels that take
/// part (the gather pass), then the residual rows built from them (a branch-free pass the
/// compiler vectorises), then the lane-wise accumulation.
struct RowScratch {
  /// per taking-part pixel: current point, warped point (X, Y, 1/Z), samples of the previous
  /// frame at W(u, T) (I, dI/du, dI/dv, D, dD/du, dD/dv, depth valid 0/1), I_i(u), w_I, w_D, gamma
  std::vector<float> x, y, z, X, Y, Z, inv_Z;
  std::vector<float> s[kLookupValid + 1];
  std::vector<float> I, wI, wD, gamma;
  /// rows: the intensity rows first, then one depth row per pixel (weight 0 without depth)
  std::vector<float> J[6];
  std::vector<float> r, w;
  /// with a brightness change: the pixel's block of the brightness fit
  std::vector<int> block;
  void reserve(std::size_t pixels);
};

/// The image term at `warp` over the current level's pixels with depth; gamma_of_label[label]
/// weights each pixel (256 entries). With `brightness` (not null), the intensity residuals carry
/// the brightness change and `blocks` (not null; reset for the level first) gets the brightness
/// fit's statistics at `warp` from the same pass; without, the residual of Eq. 61 as it stands.
void accumulateImageTerm(const DenseLevel& previous, const DenseLevel& current, const Warp& warp,
                         const float* gamma_of_label, const ResidualParams& params, RowScratch* scratch,
                         ImageNormalEquations* out, const Brightness* brightness = nullptr,
                         BrightnessBlocks* blocks = nullptr);

/// The brightness fit's statistics alone (no normal equations, no scratch), for the fit at the
/// predicted state before the first Gamma step: each pixel weighted by the previous frame's score
/// at W(u, T) (the temporal prior of Eq. 29-30: the current scores are not known yet) instead of
/// its own. `blocks` is reset for the level first.
void accumulateBrightness(const DenseLevel& previous, const DenseLevel& current, const Warp& warp,
                          const float* previous_gamma_of_label, const ResidualParams& params,
                          BrightnessBlocks* blocks);

/// Per-cluster evidence at `warp`: for every current cluster, the Eq. 60 cost of its pixels that
/// have both residuals (sum and count), and the temporal prior of Eq. 29-30: the mean previous
/// score gamma_{i-1}(W(u, T)) over its pixels that land in the previous image (sum and count;
/// previous_gamma_of_label has 256 entries).
struct ClusterEvidence {
  std::vector<double> cost_sum;
  std::vector<int> num_pixels;
  std::vector<double> prior_sum;
  std::vector<int> prior_count;
  void reset(int num_labels);
};
/// The intensity residual carries `brightness` (gain 1 and offset 0: exactly Eq. 61). Each pixel
/// adds at most `max_pixel_cost` to its cluster's cost (infinity: the cost as it is).
void clusterEvidence(const DenseLevel& previous, const DenseLevel& current, const Warp& warp,
                     const float* previous_gamma_of_label, const ResidualParams& params, const Brightness& brightness,
                     ClusterEvidence* out, float max_pixel_cost = std::numeric_limits<float>::infinity());

}  // namespace ltlo::segmentation::detail
