#include "ltlo/segmentation/dense_solver.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#include "dense_kernels.h"
#include "ltlo/core/assert.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/segmentation/gamma_step.h"

namespace ltlo::segmentation {

namespace {

/// Below this many pixels with both residuals, a cluster's mean cost is shrunk towards "no
/// evidence" (a_k = (sum - c^ n) / max(n, kMinEvidencePixels)): a few pixels say little.
constexpr int kMinEvidencePixels = 8;
/// The reference (DenseReference) is used only where it agrees with the previous frame on at least
/// this share of the pixels the previous frame finds static: one that calls most of them dynamic has
/// a pose or images that do not fit the frame's (a mover over nearly the whole view leaves a sliver
/// of background that a few pixels of pose error turn over).
constexpr double kMinReferenceAgreement = 0.5;
/// The price of calling a pixel dynamic against the reference, in units of Dense.DynamicCost: the
/// pose between the two frames comes from tracking and the IMU over several frames, so a static
/// cluster's cost grows with the baseline (pose error, more parallax at depth edges); a mover's
/// grows with its motion, several times the previous frame's.
constexpr double kReferenceCostFactor = 2.0;
/// Against the reference a pixel adds at most this many times that price to its cluster's cost, so
/// the cluster's mean exceeds the price only when about half its pixels or more disagree: a depth
/// cluster that straddles a mover's edge is not turned over by its part on the mover (which moved
/// far over the baseline and costs much), only a cluster that is mostly mover.
constexpr double kReferencePixelCostCap = 2.0;
/// Depth at which a step's image motion is measured for the convergence test, m: about the nearest
/// an RGB-D sensor measures (0.3-0.5 m); farther points move less under the same translation.
constexpr double kNearPointDepth_m = 0.5;
/// Two Gamma steps whose state weights (gamma above the static threshold, else 0) differ by at most
/// this everywhere pose the same state problem: after a converged state step, the next
/// alternation would repeat it.
constexpr float kSameStateWeight = 1e-3f;

/// Steps that shrink by less than this per step are not converging (fast enough) to bound what is
/// left of them: the solve goes on.
constexpr double kMaxContraction = 0.9;

/// A Gauss-Newton step whose brightness fit moved the predicted intensity of some grey level by
/// more than this has not converged (intensities in [0, 1]: about half an 8-bit level, a fifth of
/// the intensity noise sigma_I of 0.01-0.02 and so of no weight for the state).
constexpr double kBrightnessTolerance = 2.5e-3;
/// IRLS rounds of the brightness fit over the blocks.
constexpr int kBrightnessRounds = 3;
/// Cauchy scale of a block's residual in the brightness fit, intensity in [0, 1]: a block mean
/// that misses the affine model by several 8-bit levels is an outlier.
constexpr double kBlockResidualScale = 0.02;
/// A block takes part in the fit with at least this weight (about 4 pixels of score 1).
constexpr double kMinBlockWeight = 4.0;
/// The gain needs a weighted variance of the blocks' mean intensities (plus the prior's share) of
/// at least this (with Seg.AffineBrightnessPrior = 0 a flat image leaves the gain undetermined).
constexpr double kMinBrightnessVariance = 1e-6;
/// Bounds of the estimate: beyond them no auto-exposure step between two frames, rather a fit gone
/// wrong (e.g. a frame that is almost all one dynamic surface).
constexpr double kMinGain = 0.5;
constexpr double kMaxGain = 2.0;
constexpr double kMaxOffset = 0.5;


struct State {
  SE3 T_w_b;
  Vec3 v_w_b = Vec3::Zero();
  imu::ImuBias bias;
};

/// The warp of the current camera into an earlier one, T_prev_cur, as floats.
detail::Warp warpFrom(const SE3& T_prev_cur) {
  const Mat3 R = T_prev_cur.rotationMatrix();
  detail::Warp warp;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) warp.R[3 * r + c] = static_cast<float>(R(r, c));
    warp.t[r] = static_cast<float>(T_prev_cur.translation()(r));
  }
  return warp;
}

detail::Warp warpOf(const DensePrior& prior, const SE3& T_w_b) {
  return warpFrom((prior.T_w_b_prev * prior.T_b_c).inverse() * (T_w_b * prior.T_b_c));
}

/// The image motion still to come after a Gauss-Newton step of step_px, px, from the level's
/// previous step (previous_px, < 0 for none): near a minimum the steps shrink geometrically by
/// rho = step_px / previous_px, so the rest sums to step_px rho / (1 - rho). Without a previous
/// step, or when the steps do not shrink, nothing bounds the rest (infinity).
double remainingPx(double step_px, double previous_px) {
  if (step_px == 0.0) return 0.0;
  if (!(previous_px > 0.0) || !(step_px < kMaxContraction * previous_px)) return std::numeric_limits<double>::infinity();
  const double rho = step_px / previous_px;
  return step_px * rho / (1.0 - rho);
}

/// Information of the IMU term: the preintegration covariance widened by the previous velocity's
/// uncertainty (r_v and r_p depend on v_{i-1} through -R^T and -R^T dt).
Mat9 imuInformation(const DensePrior& prior) {
  Mat9 covariance = prior.pim->covariance();
  const double s2 = prior.prev_velocity_sigma_m_s * prior.prev_velocity_sigma_m_s;
  const double dt = prior.pim->dt_s();
  covariance.block<3, 3>(3, 3) += s2 * Mat3::Identity();
  covariance.block<3, 3>(6, 6) += s2 * dt * dt * Mat3::Identity();
  covariance.block<3, 3>(3, 6) += s2 * dt * Mat3::Identity();
  covariance.block<3, 3>(6, 3) += s2 * dt * Mat3::Identity();
  return covariance.inverse();
}

/// Information of the bias regulariser of Eq. 58 (M = 1): lambda_imu Sigma_b^-1, [b_g; b_a].
Mat6 biasInformation(const DensePrior& prior, double lambda_imu) {
  return lambda_imu * prior.pim->noise().biasWalkCovariance(std::max(prior.pim->dt_s(), imu::kMinBiasWalkInterval_s)).inverse();
}

/// Whitened motion-prior residual of a state (the IMU term, or the relative-pose prior).
double priorChi2(const DensePrior& prior, const State& state, const Mat9& imu_information) {
  if (prior.kind == DensePrior::Kind::kImu) {
    const Vec9 r = imu::inertialResidual(imu::navState(prior.T_w_b_prev, prior.v_w_b_prev),
                                         imu::navState(state.T_w_b, state.v_w_b), state.bias, *prior.pim, prior.g_w);
    return r.dot(imu_information * r);
  }
  const Vec6 r = (prior.T_w_b_pred.inverse() * state.T_w_b).log();
  return r.dot(prior.pose_information * r);
}

/// Affine brightness fit, closed form over the blocks of the current image (BrightnessBlocks).
/// Block b gives the mean current intensity X_b = 1/2 + x_b / w_b and the mean sample
/// S_b = s_b / w_b; with the weighted means X^ and S^ of the blocks, the model is
/// S_b = m + a (X_b - X^), m = a X^ + b the previous intensity of the current mean grey, and the
/// fit minimises
///   sum_b w_b rho_b (S_b - m - a (X_b - X^))^2 + lambda W [(a - 1)^2 + (m - X^)^2],
///   W = sum_b w_b rho_b,
/// a weak prior towards a = 1, b = 0 (where both terms vanish) whose weight is a share lambda of
/// the data's own, so it means the same on every level. Centred at the data's mean, the two
/// parameters separate:
///   a = (sum w rho (X - X^)(S - S^) + lambda W) / (sum w rho (X - X^)^2 + lambda W),
///   m = (S^ + lambda X^) / (1 + lambda):
/// the mean grey is always measured, the gain only as far as the blocks' spread of intensities
/// allows (a texture-poor frame keeps a ~ 1 and takes the change as offset). rho_b is the Cauchy
/// IRLS weight of the block's residual (scale kBlockResidualScale: a block on a surface the scores
/// missed, or misaligned across an edge, is an outlier), kBrightnessRounds rounds from the current
/// estimate; with `plain_first_round` (no estimate to be robust about yet, e.g. before an exposure
/// step is known) the first round weighs every block by w_b alone. The result is kept within
/// [kMinGain, kMaxGain] x [-kMaxOffset, kMaxOffset].
detail::Brightness solveBrightness(const detail::BrightnessBlocks& blocks, const detail::Brightness& current,
                                   double lambda, bool plain_first_round) {
  double a = current.gain, b = current.offset;
  const double inv_scale2 = 1.0 / (kBlockResidualScale * kBlockResidualScale);
  for (int round = 0; round < kBrightnessRounds; ++round) {
    const double round_inv_scale2 = plain_first_round && round == 0 ? 0.0 : inv_scale2;
    double sum_w = 0.0, sum_X = 0.0, sum_S = 0.0;
    auto weight = [&](std::size_t k, double* X, double* S) {
      const double w_k = blocks.w[k];
      if (!(w_k >= kMinBlockWeight)) return 0.0;
      *X = 0.5 + blocks.x[k] / w_k;
      *S = blocks.s[k] / w_k;
      const double residual = *S - (a * *X + b);
      return w_k / (1.0 + residual * residual * round_inv_scale2);
    };
    for (std::size_t k = 0; k < blocks.w.size(); ++k) {
      double X = 0.0, S = 0.0;
      const double w = weight(k, &X, &S);
      sum_w += w;
      sum_X += w * X;
      sum_S += w * S;
    }
    if (!(sum_w > 0.0)) break;
    const double mean_X = sum_X / sum_w, mean_S = sum_S / sum_w;
    double sum_xx = 0.0, sum_xs = 0.0;
    for (std::size_t k = 0; k < blocks.w.size(); ++k) {
      double X = 0.0, S = 0.0;
      const double w = weight(k, &X, &S);
      sum_xx += w * (X - mean_X) * (X - mean_X);
      sum_xs += w * (X - mean_X) * (S - mean_S);
    }
    const double prior = lambda * sum_w;
    if (sum_xx + prior > kMinBrightnessVariance * sum_w) {
      a = std::clamp((sum_xs + prior) / (sum_xx + prior), kMinGain, kMaxGain);
    }
    const double m = (mean_S + lambda * mean_X) / (1.0 + lambda);
    b = std::clamp(m - a * mean_X, -kMaxOffset, kMaxOffset);
  }
  detail::Brightness out;
  out.gain = static_cast<float>(a);
  out.offset = static_cast<float>(b);
  return out;
}

/// The largest change of a predicted intensity in [0, 1] between two brightness estimates (the
/// change is affine in I: largest at I = 0 or 1).
double brightnessChange(const detail::Brightness& a, const detail::Brightness& b) {
  const double d_offset = static_cast<double>(b.offset) - a.offset;
  const double d_gain = static_cast<double>(b.gain) - a.gain;
  return std::max(std::abs(d_offset), std::abs(d_gain + d_offset));
}

}  // namespace

struct detail::DenseSolverBuffers {
  RowScratch rows;
  ClusterEvidence evidence;
  ClusterEvidence reference_evidence;
  BrightnessBlocks blocks;
};

namespace {

/// One solve of Eq. 59 (DenseSolver::solve): the state, Gamma and the brightness change being
/// estimated, with the frames, the motion prior and the solver's buffers they are estimated from.
/// The steps of the coarse-to-fine alternation are its members.
class DenseSolve {
 public:
  DenseSolve(const DenseSolverOptions& options, detail::DenseSolverBuffers& buffers, const DenseFrame& previous,
             const std::vector<double>& previous_gamma, const DenseFrame& current,
             const std::vector<ClusterEdge>& edges, const DensePrior& prior, const DenseReference* reference);

  /// Runs the solve (once per DenseSolve).
  DenseResult run();

 private:
  /// Brightness fit alone at the state on `level`, weighted by the previous scores at W(u, T).
  void fitBrightness(int level);
  /// Gamma step at the state, on `level`: Eq. 60 evidence per cluster and the warped prior.
  void gammaStep(int level, bool record_prediction_cost);
  /// The data coefficients against the reference at the state on `level`
  /// (result_.reference_coefficient); false when the reference is not to be used (it calls most of
  /// what the previous frame finds static dynamic: its pose or images disagree with the frame's).
  bool referenceEvidence(int level);
  /// The image motion of a body step delta = [phi; rho] at `level`, px: a point kNearPointDepth_m
  /// in front of the camera moves by at most about f (|eps_phi| + |eps_rho| / z) (eps: camera twist).
  double stepPx(const Vec6& delta, int level) const;
  /// Only clusters at or above the static threshold take part in the state step (weighted by
  /// gamma): a dynamic cluster, however large, cannot pull the state. Returns the largest change
  /// of a state weight.
  float updateStateWeights();
  /// Gauss-Newton step on the state at `level` (Gamma fixed); returns the step's image motion, px.
  double stateStep(int level);
  /// The image term's normal equations at the state on `level`. With the brightness change, the
  /// same pass gives the brightness fit at the step's start (both updates from one linearisation
  /// point).
  void accumulateImageTerm(int level, detail::ImageNormalEquations* image);
  /// The state step with the IMU term and the bias regulariser, from the image term's normal
  /// equations in the body twist.
  double imuStateStep(const Mat6& H_pose, const Vec6& b_pose, int level);
  /// The pose step with the relative-pose prior, from the image term's normal equations in the
  /// body twist.
  double relativePoseStateStep(const Mat6& H_pose, const Vec6& b_pose, int level);
  /// Up to Dense.IterationsPerLevel Gauss-Newton steps on `level`, until the motion still to come
  /// (from the level's last step, *previous_step_px) and the brightness fit's change are small
  /// enough; returns whether they converged.
  bool gaussNewtonSteps(int level, double* previous_step_px);
  /// The alternations of every level, coarse to fine; returns whether Gamma was last solved at the
  /// final state on the finest level.
  bool alternateOverLevels(int coarsest, int finest);
  /// The prior gate: false (and the state back at the prediction) when the refined state's prior
  /// residual exceeds Dense.MaxPriorChi2.
  bool passesPriorGate(int finest);
  /// The result from the solve's state and scores.
  DenseResult takeResult();

  const DenseSolverOptions& options_;
  detail::DenseSolverBuffers& buffers_;
  const DenseFrame& previous_;
  const DenseFrame& current_;
  const DensePrior& prior_;
  const DenseReference* reference_;  ///< null: the previous frame alone
  int reference_level_ = -1;         ///< the level result_.reference_coefficient was taken on
  bool reference_used_ = false;      ///< and whether it is used there
  const int num_clusters_;  ///< K of the current frame
  const bool with_imu_;
  const detail::ResidualParams params_;
  const Mat9 imu_information_;
  const Mat6 bias_information_;
  const Mat6 A_;  ///< camera twist eps = Ad(T_c_b) body twist delta

  std::array<float, kMaxClusterLabels> previous_gamma_of_label_;
  std::array<float, kMaxClusterLabels> gamma_of_label_;
  std::array<float, kMaxClusterLabels> state_weight_of_label_;
  State state_;
  DenseResult result_;
  std::vector<double> gamma_;
  GammaProblem problem_;

  // The brightness change (gain 1, offset 0 and never updated with Seg.AffineBrightness off).
  const bool with_brightness_;
  detail::Brightness brightness_;
  double brightness_change_ = 0.0;  // of the last state step's fit
};

DenseSolve::DenseSolve(const DenseSolverOptions& options, detail::DenseSolverBuffers& buffers,
                       const DenseFrame& previous, const std::vector<double>& previous_gamma,
                       const DenseFrame& current, const std::vector<ClusterEdge>& edges, const DensePrior& prior,
                       const DenseReference* reference)
    : options_(options),
      buffers_(buffers),
      previous_(previous),
      current_(current),
      prior_(prior),
      reference_(reference),
      num_clusters_(current.numClusters()),
      with_imu_(prior.kind == DensePrior::Kind::kImu),
      params_{static_cast<float>(options.alpha_intensity), static_cast<float>(options.cauchy_c),
              static_cast<float>(options.occlusion_gap_m)},
      imu_information_(with_imu_ ? imuInformation(prior) : Mat9::Identity()),
      bias_information_(with_imu_ ? biasInformation(prior, options.lambda_imu) : Mat6::Identity()),
      A_(prior.T_b_c.inverse().adjoint()),
      gamma_(static_cast<std::size_t>(num_clusters_), 1.0),
      with_brightness_(options.affine_brightness) {
  previous_gamma_of_label_.fill(1.0f);
  for (std::size_t k = 0; k < previous_gamma.size(); ++k) previous_gamma_of_label_[k] = static_cast<float>(previous_gamma[k]);
  gamma_of_label_.fill(1.0f);
  state_weight_of_label_.fill(0.0f);

  state_.T_w_b = prior.T_w_b_pred;
  state_.v_w_b = prior.v_w_b_pred;
  state_.bias = prior.bias_prev;

  problem_.edges = edges;
  problem_.lambda_d = options.lambda_d;
  problem_.data.assign(static_cast<std::size_t>(num_clusters_), 0.0);
  problem_.prior.assign(static_cast<std::size_t>(num_clusters_), 1.0);
}

void DenseSolve::fitBrightness(int level) {
  detail::accumulateBrightness(previous_.level(level), current_.level(level), warpOf(prior_, state_.T_w_b),
                               previous_gamma_of_label_.data(), params_, &buffers_.blocks);
  brightness_ = solveBrightness(buffers_.blocks, brightness_, options_.brightness_prior, /*plain_first_round=*/true);
}

void DenseSolve::gammaStep(int level, bool record_prediction_cost) {
  const int K = num_clusters_;
  detail::ClusterEvidence& evidence = buffers_.evidence;
  evidence.reset(K + 1);
  detail::clusterEvidence(previous_.level(level), current_.level(level), warpOf(prior_, state_.T_w_b),
                          previous_gamma_of_label_.data(), params_, brightness_, &evidence);
  if (record_prediction_cost) result_.cost_at_prediction.assign(static_cast<std::size_t>(K) + 1, -1.0);
  for (int k = 0; k < K; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    const int n = evidence.num_pixels[kk];
    problem_.data[kk] = (evidence.cost_sum[kk] - options_.dynamic_cost * n) / std::max(n, kMinEvidencePixels);
    const int m = evidence.prior_count[kk];
    problem_.prior[kk] = m > 0 ? evidence.prior_sum[kk] / m : 1.0;
    if (record_prediction_cost && n > 0) result_.cost_at_prediction[kk] = evidence.cost_sum[kk] / n;
  }
  // Against the reference once per level (at the level's first Gamma step): the later steps' state
  // differs by a fraction of a pixel of the level, which the baseline's motion dwarfs.
  if (reference_ != nullptr && level != reference_level_) {
    reference_level_ = level;
    reference_used_ = referenceEvidence(level);
  }
  if (reference_used_) {
    for (int k = 0; k < K; ++k) {
      const auto kk = static_cast<std::size_t>(k);
      problem_.data[kk] = std::max(problem_.data[kk], result_.reference_coefficient[kk]);
    }
  }
  gamma_ = solveGamma(problem_, gamma_);
  for (int k = 0; k < K; ++k) gamma_of_label_[static_cast<std::size_t>(k)] = static_cast<float>(gamma_[static_cast<std::size_t>(k)]);
}

bool DenseSolve::referenceEvidence(int level) {
  const int K = num_clusters_;
  const detail::Warp warp = warpFrom(reference_->T_w_c.inverse() * (state_.T_w_b * prior_.T_b_c));
  // I_ref ~ g I_prev + o and I_prev ~ a I_cur + b: I_ref ~ g a I_cur + (g b + o).
  detail::Brightness brightness;
  brightness.gain = static_cast<float>(reference_->gain * brightness_.gain);
  brightness.offset = static_cast<float>(reference_->gain * brightness_.offset + reference_->offset);
  detail::ClusterEvidence& evidence = buffers_.reference_evidence;
  evidence.reset(K + 1);
  // The temporal prior this pass also sums is not used (the previous frame's is).
  const double price = kReferenceCostFactor * options_.dynamic_cost;
  detail::clusterEvidence(reference_->frame->level(level), current_.level(level), warp,
                          previous_gamma_of_label_.data(), params_, brightness, &evidence,
                          static_cast<float>(kReferencePixelCostCap * price));
  result_.reference_coefficient.assign(static_cast<std::size_t>(K) + 1, 0.0);
  // The pixels the previous frame finds static (problem_.data < 0) and the share of them the
  // reference agrees with.
  long static_px = 0, agreeing_px = 0;
  for (int k = 0; k < K; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    const int n = evidence.num_pixels[kk];
    result_.reference_coefficient[kk] =
        (evidence.cost_sum[kk] - price * n) / std::max(n, kMinEvidencePixels);
    if (problem_.data[kk] < 0.0 && n >= kMinEvidencePixels) {
      const int n_frame = buffers_.evidence.num_pixels[kk];
      static_px += n_frame;
      if (result_.reference_coefficient[kk] <= 0.0) agreeing_px += n_frame;
    }
  }
  result_.reference_used = static_px > 0 && agreeing_px >= kMinReferenceAgreement * static_px;
  return result_.reference_used;
}

double DenseSolve::stepPx(const Vec6& delta, int level) const {
  const Vec6 eps = A_ * delta;
  return current_.level(level).camera.fx * (eps.head<3>().norm() + eps.tail<3>().norm() / kNearPointDepth_m);
}

float DenseSolve::updateStateWeights() {
  float largest_change = 0.0f;
  for (std::size_t k = 0; k < state_weight_of_label_.size(); ++k) {
    const float weight = gamma_of_label_[k] >= options_.static_threshold ? gamma_of_label_[k] : 0.0f;
    largest_change = std::max(largest_change, std::abs(weight - state_weight_of_label_[k]));
    state_weight_of_label_[k] = weight;
  }
  return largest_change;
}

void DenseSolve::accumulateImageTerm(int level, detail::ImageNormalEquations* image) {
  if (with_brightness_) {
    detail::accumulateImageTerm(previous_.level(level), current_.level(level), warpOf(prior_, state_.T_w_b),
                                state_weight_of_label_.data(), params_, &buffers_.rows, image, &brightness_,
                                &buffers_.blocks);
    const detail::Brightness fitted =
        solveBrightness(buffers_.blocks, brightness_, options_.brightness_prior, /*plain_first_round=*/false);
    brightness_change_ = brightnessChange(brightness_, fitted);
    brightness_ = fitted;
  } else {
    detail::accumulateImageTerm(previous_.level(level), current_.level(level), warpOf(prior_, state_.T_w_b),
                                state_weight_of_label_.data(), params_, &buffers_.rows, image);
  }
}

double DenseSolve::stateStep(int level) {
  detail::ImageNormalEquations image;
  accumulateImageTerm(level, &image);
  ++result_.gauss_newton_steps;
  const Mat6 H_pose = A_.transpose() * image.H * A_;
  const Vec6 b_pose = A_.transpose() * image.b;
  if (with_imu_) return imuStateStep(H_pose, b_pose, level);
  return relativePoseStateStep(H_pose, b_pose, level);
}

double DenseSolve::imuStateStep(const Mat6& H_pose, const Vec6& b_pose, int level) {
  Mat15 H = Mat15::Zero();
  Vec15 b = Vec15::Zero();
  H.block<6, 6>(0, 0) = H_pose;
  b.head<6>() = b_pose;
  const imu::InertialResidualJacobians jac = imu::inertialResidualJacobians(
      imu::navState(prior_.T_w_b_prev, prior_.v_w_b_prev), imu::navState(state_.T_w_b, state_.v_w_b), state_.bias,
      *prior_.pim, prior_.g_w);
  Eigen::Matrix<double, 9, 15> J;
  J << jac.d_r_d_R_j, jac.d_r_d_p_j * state_.T_w_b.rotationMatrix(), jac.d_r_d_v_j, jac.d_r_d_b_g, jac.d_r_d_b_a;
  H += J.transpose() * imu_information_ * J;
  b += J.transpose() * imu_information_ * jac.residual;
  Vec6 r_bias;
  r_bias << state_.bias.b_g - prior_.bias_prev.b_g, state_.bias.b_a - prior_.bias_prev.b_a;
  H.block<6, 6>(9, 9) += bias_information_;
  b.tail<6>() += bias_information_ * r_bias;
  const Vec15 delta = -H.ldlt().solve(b);
  if (!delta.allFinite()) return 0.0;
  state_.T_w_b = state_.T_w_b * SE3::exp(delta.head<6>());
  state_.v_w_b += delta.segment<3>(6);
  state_.bias.b_g += delta.segment<3>(9);
  state_.bias.b_a += delta.segment<3>(12);
  return stepPx(delta.head<6>(), level);
}

double DenseSolve::relativePoseStateStep(const Mat6& H_pose, const Vec6& b_pose, int level) {
  // Relative-pose prior r = Log(T_pred^-1 T) with d r / d delta ~ I near the prediction.
  const Vec6 r = (prior_.T_w_b_pred.inverse() * state_.T_w_b).log();
  const Mat6 H = H_pose + prior_.pose_information;
  const Vec6 b = b_pose + prior_.pose_information * r;
  const Vec6 delta = -H.ldlt().solve(b);
  if (!delta.allFinite()) return 0.0;
  state_.T_w_b = state_.T_w_b * SE3::exp(delta);
  return stepPx(delta, level);
}

bool DenseSolve::gaussNewtonSteps(int level, double* previous_step_px) {
  bool converged = false;
  for (int iteration = 0; iteration < options_.iterations_per_level && !converged; ++iteration) {
    const double step_px = stateStep(level);
    converged = remainingPx(step_px, *previous_step_px) <= options_.step_tolerance_px &&
                brightness_change_ <= kBrightnessTolerance;
    *previous_step_px = step_px;
  }
  return converged;
}

bool DenseSolve::alternateOverLevels(int coarsest, int finest) {
  bool gamma_at_final_state = false;
  for (int level = coarsest; level >= finest; --level) {
    bool converged = false;
    double previous_step_px = -1.0;  // the level's last step, px (< 0: none yet)
    for (int alternation = 0; alternation < options_.alternations; ++alternation) {
      gammaStep(level, level == coarsest && alternation == 0);
      const float weight_change = updateStateWeights();
      if (converged && weight_change <= kSameStateWeight) {
        // The state step converged and Gamma poses it the same problem: the remaining
        // alternations of this level would repeat the same two steps.
        gamma_at_final_state = level == finest;
        break;
      }
      converged = gaussNewtonSteps(level, &previous_step_px);
    }
  }
  return gamma_at_final_state;
}

bool DenseSolve::passesPriorGate(int finest) {
  result_.prior_chi2 = priorChi2(prior_, state_, imu_information_);
  if (result_.prior_chi2 > options_.max_prior_chi2) {
    // The images pulled the state away from the motion prior: keep the prediction.
    result_.prior_rejected = true;
    state_.T_w_b = prior_.T_w_b_pred;
    state_.v_w_b = prior_.v_w_b_pred;
    state_.bias = prior_.bias_prev;
    result_.prior_chi2 = priorChi2(prior_, state_, imu_information_);
    if (with_brightness_) fitBrightness(finest);  // the brightness change at the kept prediction
    return false;
  }
  return true;
}

DenseResult DenseSolve::takeResult() {
  result_.state_refined = num_clusters_ > 0 && !result_.prior_rejected;
  result_.T_w_b = state_.T_w_b;
  result_.v_w_b = state_.v_w_b;
  result_.bias = state_.bias;
  result_.brightness_gain = brightness_.gain;
  result_.brightness_offset = brightness_.offset;
  result_.gamma = gamma_;
  result_.gamma.push_back(1.0);  // the no-depth cluster K
  result_.prior_gamma = problem_.prior;
  result_.prior_gamma.push_back(1.0);
  result_.data_coefficient = problem_.data;
  result_.data_coefficient.push_back(0.0);
  return std::move(result_);
}

DenseResult DenseSolve::run() {
  const int coarsest = current_.numLevels() - 1;
  const int finest = std::clamp(options_.finest_level, 0, coarsest);
  if (num_clusters_ > 0) {
    // The brightness change before the first Gamma step judges the clusters: an exposure step
    // would otherwise raise every cluster's cost at the prediction.
    if (with_brightness_) fitBrightness(coarsest);
    // Gamma was last solved at the current state on the finest level (the final Gamma step would
    // repeat it).
    bool gamma_at_final_state = alternateOverLevels(coarsest, finest);
    if (!passesPriorGate(finest)) gamma_at_final_state = false;
    if (!gamma_at_final_state) gammaStep(finest, false);
  }
  return takeResult();
}

}  // namespace

DenseSolverOptions DenseSolverOptions::from(const SegmentationOptions& segmentation, const DenseOptions& dense,
                                            const LocalMappingOptions& local_mapping) {
  DenseSolverOptions options;
  options.alpha_intensity = segmentation.alpha_intensity;
  options.cauchy_c = segmentation.cauchy_c;
  options.dynamic_cost = dense.dynamic_cost;
  options.occlusion_gap_m = dense.occlusion_gap_m;
  options.lambda_d = dense.lambda_d;
  options.static_threshold = segmentation.static_threshold;
  options.lambda_imu = local_mapping.lambda_imu;
  options.iterations_per_level = dense.iterations_per_level;
  options.alternations = dense.alternations;
  options.finest_level = dense.finest_level;
  options.step_tolerance_px = dense.step_tolerance_px;
  options.max_prior_chi2 = dense.max_prior_chi2;
  options.affine_brightness = segmentation.affine_brightness;
  options.brightness_prior = segmentation.affine_brightness_prior;
  return options;
}

DenseSolver::DenseSolver(const DenseSolverOptions& options)
    : options_(options), buffers_(std::make_unique<detail::DenseSolverBuffers>()) {
  LTLO_ASSERT(options.iterations_per_level >= 1 && options.alternations >= 1,
              "iterations " << options.iterations_per_level << ", alternations " << options.alternations);
  LTLO_ASSERT(options.step_tolerance_px >= 0.0, "step tolerance " << options.step_tolerance_px << " px");
  LTLO_ASSERT(options.cauchy_c > 0.0 && options.lambda_d >= 0.0, "cauchy_c " << options.cauchy_c << ", lambda_d "
                                                                             << options.lambda_d);
  LTLO_ASSERT(options.brightness_prior >= 0.0, "brightness prior " << options.brightness_prior);
}

DenseSolver::~DenseSolver() = default;

DenseResult DenseSolver::solve(const DenseFrame& previous, const std::vector<double>& previous_gamma,
                               const DenseFrame& current, const std::vector<ClusterEdge>& edges,
                               const DensePrior& prior, const DenseReference* reference) {
  LTLO_ASSERT(!previous.empty() && !current.empty() && previous.numLevels() == current.numLevels(),
              "dense frames of " << previous.numLevels() << " and " << current.numLevels() << " levels");
  LTLO_ASSERT(static_cast<int>(previous_gamma.size()) == previous.numClusters() + 1,
              previous_gamma.size() << " previous scores for " << previous.numClusters() << " clusters");
  LTLO_ASSERT(prior.kind != DensePrior::Kind::kImu || prior.pim != nullptr, "an IMU prior needs the preintegration");
  LTLO_ASSERT(reference == nullptr || (reference->frame != nullptr && reference->frame->numLevels() == current.numLevels()),
              "a reference frame without the current frame's levels");
  return DenseSolve(options_, *buffers_, previous, previous_gamma, current, edges, prior, reference).run();
}

}  // namespace ltlo::segmentation
