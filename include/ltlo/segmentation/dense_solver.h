#pragma once
/// The dense initial state and segmentation of one frame (thesis Eq. 59-64):
///
///   min_{S_i, Gamma_i}  ||r_imu(S_{i-1}, S_i)||^2_Sigma                                (IMU term)
///                     + sum_u gamma(u) [F(alpha_I w_I r_I) + F(w_D r_D) - c^]          (Eq. 60)
///                     + lambda_d R_d(Gamma_i)                                          (Eq. 54)
///                     + lambda_imu ||b_i - b_{i-1}||^2_Sigma_b                         (Eq. 58, M = 1)
///
/// over the current state S_i = {T_w_b, v_w_b, b_g, b_a} with the previous state S_{i-1} fixed and
/// the cluster scores Gamma_i in [0, 1]. F is the Cauchy penalty, w_I and w_D the weights of Eq. 64
/// (DenseFrame), r_I and r_D the residuals of Eq. 61-62 at the pixels with depth.
///
/// c^ (Dense.DynamicCost) is the price of calling a pixel dynamic, the tracking counterpart of the
/// (1 - gamma) c^ term of Eq. 53: Eq. 60 is linear in gamma, so without it every score would sink
/// to 0 or rest on the prior alone. A constant per pixel, it leaves the state step unchanged; in the
/// Gamma step it makes the data coefficient a_k = (mean Eq. 60 cost of cluster k per pixel) - c^,
/// negative (evidence of static) below c^, positive above. The per-pixel mean (not the sum) keeps
/// large and small clusters comparable with the per-cluster prior and smoothness of Eq. 54.
///
/// gamma~ (the prior of Eq. 54) is the previous frame's Gamma carried to the current clusters by the
/// static motion (thesis ch. 4 Eq. 29-30): the mean previous score at W(u, T) over each cluster's
/// pixels; 1 where nothing maps into the previous image.
///
/// Solver: coarse to fine over the pyramid; on each level, Dense.Alternations times: Gamma step
/// (state fixed, closed form, gamma_step.h), then up to Dense.IterationsPerLevel Gauss-Newton steps
/// on the state (Gamma fixed), fewer once a step moves the image by less than Dense.StepTolerance;
/// a last Gamma step at the finest level. An alternation whose Gamma step leaves the state weights
/// as they were after a converged state step ends the level (the rest would repeat it), and the
/// last Gamma step is skipped when it would see the same state again. The first Gamma step runs at the
/// predicted state, so each cluster is judged by its residual under the IMU-predicted motion before
/// any image alignment, and a dominant moving cluster starts the state step with a low weight.
/// After the solve, a state whose motion-prior residual exceeds Dense.MaxPriorChi2 is rejected
/// (the images pulled it away from the IMU): the state falls back to the prediction and Gamma is
/// solved again there.
///
/// Brightness (Seg.AffineBrightness, issue 28): auto-exposure changes the intensities between the
/// frames, which Eq. 61 would read as motion or as dynamic clusters. With the switch on, the
/// intensity residual carries a per-frame affine change, r_I = I_{i-1}(W(u, T)) - (a I_i(u) + b)
/// (gain a = previous over current exposure, offset b, intensities in [0, 1]), estimated inside
/// the solve in closed form ("affine brightness fit", dense_solver.cc): a weighted least-squares
/// line through the 8 x 8 block means of the current intensities and of the warped samples (block
/// means, because a bilinear sample flattens a texture's peaks, and a pixel-wise fit would read
/// every textured pair as a gain below 1), weighted by the clusters' scores, robust (Cauchy) per
/// block, with a weak prior towards a = 1, b = 0 (Seg.AffineBrightnessPrior) so that a
/// texture-poor frame keeps its gain. It is fitted first at the predicted state on the coarsest
/// level (weighted by the previous scores at W(u, T)), before the first Gamma step judges the
/// clusters, then after every Gauss-Newton step from that step's own pass, carried from coarse to
/// fine like the state; a level's Gauss-Newton steps go on while the fit still moves a predicted
/// intensity by more than about half an 8-bit level. With the switch off the solve is Eq. 61 as
/// it stands, bit for bit the same as before the brightness change existed.
///
/// Before the IMU is initialised and without an IMU, the IMU term is replaced by a Gaussian prior on
/// the relative pose (kRelativePose: gyroscope rotation or constant angular rate, constant-velocity
/// translation); velocity and biases are then not estimated.
#include <memory>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/segmentation/cluster_map.h"
#include "ltlo/segmentation/dense_frame.h"

namespace ltlo::segmentation {

struct DenseSolverOptions {
  /// alpha_I of Eq. 60 (Seg.AlphaIntensity)
  double alpha_intensity = 0.15;
  /// c of the Cauchy penalty F on weighted residuals (Seg.CauchyC)
  double cauchy_c = 0.5;
  /// c^, price per pixel of calling it dynamic, in units of F (Dense.DynamicCost)
  double dynamic_cost = 0.25;
  /// a pixel whose warped point lies this far behind the previous depth was hidden in the previous
  /// frame: no residual, evidence or prior from it, m (Dense.OcclusionGap)
  double occlusion_gap_m = 0.1;
  /// lambda_d of Eq. 54 in Eq. 59 (Dense.LambdaD)
  double lambda_d = 0.1;
  /// clusters below this score do not take part in the state step (Seg.StaticThreshold)
  double static_threshold = 0.5;
  /// lambda_imu of Eq. 58 (LocalMapping.LambdaImu)
  double lambda_imu = 1.0;
  /// Gauss-Newton steps per level and alternation (Dense.IterationsPerLevel)
  int iterations_per_level = 5;
  /// Gamma <-> state alternations per level (Dense.Alternations)
  int alternations = 2;
  /// finest pyramid level the state is solved on (Dense.FinestLevel; 0 = Dense.Resolution)
  int finest_level = 1;
  /// Gauss-Newton stops on a level once the image motion still to come, estimated from the level's
  /// last two steps, is at most this, px of the level (Dense.StepTolerance)
  double step_tolerance_px = 0.01;
  /// prior residual (chi^2, whitened) above which the refined state is rejected (Dense.MaxPriorChi2)
  double max_prior_chi2 = 30.0;
  /// estimate the affine brightness change between the frames (Seg.AffineBrightness)
  bool affine_brightness = true;
  /// weight of the brightness prior towards gain 1, offset 0, as a share of the fit's total weight
  /// (Seg.AffineBrightnessPrior)
  double brightness_prior = 1e-5;

  static DenseSolverOptions from(const SegmentationOptions& segmentation, const DenseOptions& dense,
                                 const LocalMappingOptions& local_mapping);
};

/// The motion information of Eq. 59 for one frame pair.
struct DensePrior {
  enum class Kind {
    kRelativePose,  ///< Gaussian prior on T_w_b around T_w_b_pred (pose_information)
    kImu,           ///< the IMU term from the preintegration + the bias regulariser (Eq. 58)
  };
  Kind kind = Kind::kRelativePose;
  /// The previous frame's state (held fixed) and the predicted current state.
  SE3 T_w_b_prev;
  Vec3 v_w_b_prev = Vec3::Zero();
  imu::ImuBias bias_prev;
  SE3 T_w_b_pred;
  Vec3 v_w_b_pred = Vec3::Zero();
  /// body -> camera
  SE3 T_b_c;
  /// kRelativePose: information of the body pose perturbation delta (T_w_b = T_w_b_pred Exp(delta),
  /// delta = [phi; rho]), 1/rad^2, 1/m^2
  Mat6 pose_information = Mat6::Identity();
  /// kImu: preintegration previous -> current at bias_prev (not owned; lives for the solve), gravity
  const imu::Preintegrated* pim = nullptr;
  Vec3 g_w = Vec3(0.0, 0.0, -9.81);
  /// kImu: standard deviation of the previous frame's velocity, m/s: the previous state is held
  /// fixed, so its velocity error widens the IMU residual's velocity and position covariance.
  double prev_velocity_sigma_m_s = 0.05;
};

/// An earlier frame that judges the clusters over a longer baseline than the previous frame's
/// (Dense.ReferenceBaseline). On each pyramid level (at its first Gamma step, then kept for the
/// level) each current cluster's mean Eq. 60 cost is also taken against this frame at the state
/// (warp T_ref_cur = T_w_c_ref^-1 T_w_b T_b_c, the same occlusion rule), at twice the price per pixel
/// and with each pixel's cost capped at twice that price (a cluster that straddles a mover's edge is
/// not turned over by its part on the mover), and the cluster's data coefficient is the larger of
/// the two: the reference can only call a cluster more dynamic. A reference that calls most of the
/// pixels the previous frame finds static dynamic is not used. A surface seen behind the reference's (a box there then, gone now) gives
/// no evidence, so a mover of the reference does not make the background dynamic; a surface now in
/// front of the reference's (a mover come closer) or beside it does.
struct DenseReference {
  /// built with the same options as the current frame, its labels set (not owned)
  const DenseFrame* frame = nullptr;
  /// the reference camera in the world of the prior
  SE3 T_w_c;
  /// brightness from the reference to the previous frame, I_ref(x) ~ gain I_prev(x) + offset (the
  /// solve composes it with its own estimate previous -> current)
  double gain = 1.0;
  double offset = 0.0;
};

/// What the solve found.
struct DenseResult {
  SE3 T_w_b;
  Vec3 v_w_b = Vec3::Zero();
  imu::ImuBias bias;
  /// Gamma_i: K + 1 scores, the last (no depth) 1
  std::vector<double> gamma;
  /// gamma~ used by the last Gamma step (K + 1)
  std::vector<double> prior_gamma;
  /// mean Eq. 60 cost per pixel of each cluster at the predicted state on the coarsest level
  /// (K + 1; -1 where a cluster had no pixel with both residuals), diagnostics
  std::vector<double> cost_at_prediction;
  /// a_k of the last Gamma step (K + 1; 0 for the no-depth cluster), diagnostics
  std::vector<double> data_coefficient;
  /// With a reference: the data coefficient against it in the last Gamma step (K + 1; 0 for the
  /// no-depth cluster; empty without a reference), diagnostics
  std::vector<double> reference_coefficient;
  /// the reference was used in the last Gamma step (it agreed with the previous frame on most of
  /// what that finds static)
  bool reference_used = false;
  /// the state moved from the prediction and passed the prior gate
  bool state_refined = false;
  /// the refined state failed the prior gate (state = prediction)
  bool prior_rejected = false;
  /// whitened prior residual of the final state
  double prior_chi2 = 0.0;
  /// the brightness change found, I_{i-1}(W(u, T)) ~ gain I_i(u) + offset (1 and 0 with
  /// Seg.AffineBrightness off)
  double brightness_gain = 1.0;
  double brightness_offset = 0.0;
  int gauss_newton_steps = 0;
};

namespace detail {
struct DenseSolverBuffers;
}

/// Not thread-safe (the tracking thread owns one); keeps its buffers between frames.
class DenseSolver {
 public:
  explicit DenseSolver(const DenseSolverOptions& options);
  ~DenseSolver();

  /// Solves Eq. 59 for `current` against `previous` (both built with the same options, labels set)
  /// whose scores were `previous_gamma` (previous.numClusters() + 1 entries). `edges` is V_i of the
  /// current clusters. With `reference` (not null), an earlier frame judges the clusters too
  /// (DenseReference).
  DenseResult solve(const DenseFrame& previous, const std::vector<double>& previous_gamma,
                    const DenseFrame& current, const std::vector<ClusterEdge>& edges, const DensePrior& prior,
                    const DenseReference* reference = nullptr);

  const DenseSolverOptions& options() const { return options_; }

 private:
  DenseSolverOptions options_;
  std::unique_ptr<detail::DenseSolverBuffers> buffers_;
};

}  // namespace ltlo::segmentation
