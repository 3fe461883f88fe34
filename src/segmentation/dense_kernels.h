#pragma once
// Per-pixel kernels of the dense initial state and segmentation (thesis Eq. 60-64): warping the
// current frame's pixels into the previous frame (Eq. 63), the intensity and depth residuals
// (Eq. 61-62) with the weights of Eq. 64 and the Cauchy penalty, accumulated into the normal
// equations of the camera motion or into per-cluster evidence. Compiled at -O3: the accumulation
// is written over fixed-width lanes so the compiler vectorises it.
#include <cstdint>
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
  void reserve(std::size_t pixels);
};

/// The image term at `warp` over the current level's pixels with depth; gamma_of_label[label]
/// weights each pixel (256 entries).
void accumulateImageTerm(const DenseLevel& previous, const DenseLevel& current, const Warp& warp,
                         const float* gamma_of_label, const ResidualParams& params, RowScratch* scratch,
                         ImageNormalEquations* out);

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
void clusterEvidence(const DenseLevel& previous, const DenseLevel& current, const Warp& warp,
                     const float* previous_gamma_of_label, const ResidualParams& params, ClusterEvidence* out);

}  // namespace ltlo::segmentation::detail
