#pragma once
/// Window problems on plain inputs (namespace ltlo::optim): local and full visual(-inertial) bundle
/// adjustment (with the gravity direction as an unknown for the IMU-initialisation refinement) and
/// inertial-only IMU initialisation. Inputs are ids + Eigen values so optim does not depend on
/// map/; the caller copies states in and writes results back under its own locks.
#include <atomic>
#include <memory>
#include <optional>
#include <vector>

#include <sparse_opt/graph.h>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/optim/reprojection_edges.h"

namespace ltlo::optim {

struct BaKeyFrame {
  int id = 0;
  SE3 T_w_b;
  Vec3 v_w_b = Vec3::Zero();  ///< used when the keyframe has an inertial link
  imu::ImuBias bias;          ///< used when the keyframe has an inertial link
  bool fixed = false;         ///< in the problem as a constraint only (gauge, window border)
  /// With `fixed`: only the pose is held (the gauge of a full visual-inertial BA); the velocity and
  /// biases are optimised.
  bool fixed_pose_only = false;
  /// With `fixed`: the velocity is optimised, the pose and biases held (a map's gauge keyframe in a
  /// local visual-inertial window: its velocity may be dead-reckoned, mapping::WindowBaOptions).
  bool velocity_free = false;
  /// With `velocity_free`: a prior on the velocity about velocity_prior with this standard
  /// deviation (m/s; 0: none).
  double velocity_prior_sigma_m_s = 0.0;
  Vec3 velocity_prior = Vec3::Zero();
};

struct BaPoint {
  int id = 0;
  Vec3 p_w = Vec3::Zero();
};

struct BaObservation {
  int keyframe_id = 0;
  int point_id = 0;
  Vec2 uv = Vec2::Zero();      ///< keypoint (px)
  double depth_m = 0.0;        ///< <= 0: monocular 2-D edge
  double sigma_px = 1.0;
  double static_weight = 1.0;  ///< beta * gamma (thesis Eq. 53)
};

/// IMU between consecutive keyframes i -> j (the deltas are corrected for the biases of i).
struct BaInertialLink {
  int keyframe_i = 0;
  int keyframe_j = 0;
  std::shared_ptr<const imu::Preintegrated> pim;
};

/// Prior r = b - mean on the biases of one keyframe with an inertial link (per-axis information).
struct BaBiasPrior {
  int keyframe_id = 0;
  imu::ImuBias mean;
  double gyro_information = 0.0;  ///< 1/(rad/s)^2
  double acc_information = 0.0;   ///< 1/(m/s^2)^2
};

struct LocalBaProblem {
  ProjectionModel model;  ///< T_c_x = T_c_b
  std::vector<BaKeyFrame> keyframes;
  std::vector<BaPoint> points;
  std::vector<BaObservation> observations;
  std::vector<BaInertialLink> inertial;  ///< empty: visual-only BA
  /// Gravity in w (m/s^2); with estimate_gravity, the start of its direction (magnitude kept).
  Vec3 g_w = imu::gravityWorld();
  /// Optimise the gravity direction (2 DoF, EdgeInertialGravity) with the states: the visual-inertial
  /// refinement of the IMU initialisation. Needs inertial links.
  bool estimate_gravity = false;
  double lambda_imu = 1.0;  ///< bias random-walk weight (thesis Eq. 58)
  /// Standard deviation (m/s^2) to which the accelerometer bias of a held keyframe is known: the
  /// random-walk link from a held keyframe's bias to a free one's adds it (squared) to the walk's
  /// covariance, so the window may move its biases as far as the estimate they were held at is
  /// uncertain (an IMU initialisation from a short window). 0: held biases are exact (Eq. 58 alone).
  double held_acc_bias_sigma_m_s2 = 0.0;
  std::vector<BaBiasPrior> bias_priors;  ///< keyframes must have an inertial link
  /// Multiplies the information of the inertial, bias random-walk and bias-prior edges
  /// (inertialInformationScale: the camera's variance factor), so camera and IMU count by their
  /// actual noise while the reprojection edges keep their 1 px-per-level model, Huber kernel and
  /// chi2 gates (the same outlier decisions as every other BA).
  double inertial_information_scale = 1.0;
};

/// A posteriori variance factor of the reprojection edges at the problem's start values (Helmert's
/// variance component for the camera): the median over observations of r^T Omega r divided by the
/// median of the chi-square distribution with the edge's dof (3 RGB-D, 2 monocular), so outliers and
/// moving points (static weight < 0.5 are left out) barely move it. 1: the residuals are as the model
/// says (sigma_px per level); 0.1: the keypoints are sqrt(10) times more precise than modelled.
/// 1 with fewer than 10 usable observations. Reads the problem only.
double visualVarianceFactor(const LocalBaProblem& problem);
/// visualVarianceFactor clamped to [1e-2, 1e2]: the inertial_information_scale of a visual-inertial
/// problem whose camera noise is not known better than the 1 px-per-level model (scaling the IMU
/// side by the factor has the optimum of scaling the camera side by its inverse).
double inertialInformationScale(const LocalBaProblem& problem);

struct LocalBaOptions {
  int iterations = 10;
  /// After a first pass, drop observations failing the chi2 test (or behind the camera) and run
  /// `iterations` more without robust kernels (ORB-SLAM's local BA).
  bool reject_outliers = true;
  double chi2_2d = kChi2Threshold2Dof;
  double chi2_3d = kChi2Threshold3Dof;
  int num_threads = 2;
  const std::atomic<bool>* stop_flag = nullptr;  ///< checked between iterations (new keyframe)
};

struct LocalBaResult {
  std::vector<BaKeyFrame> keyframes;  ///< input order, optimised values
  std::vector<BaPoint> points;        ///< input order
  std::vector<bool> inliers;          ///< per observation
  /// Per observation r^T Omega_obs r at the result, without the static weight: the |r|^2 of the
  /// thesis' Eq. 53 (staticWeightedCost) for the closed-form weight updates.
  std::vector<double> residual_chi2;
  Vec3 g_w = Vec3::Zero();            ///< problem.g_w, or the optimised one with estimate_gravity
  sparse_opt::Summary summary;        ///< of the last pass
  double initial_chi2 = 0.0;          ///< of the first pass (robust), before any step
};

/// Throws LTLO assertion errors on unknown ids; observations of points/keyframes not given are bugs.
LocalBaResult localBundleAdjust(const LocalBaProblem& problem, const LocalBaOptions& options = LocalBaOptions());

/// Per-axis information of the zero-mean bias priors of the IMU initialisation and its refinement:
/// the evidence of `samples` IMU readings that the bias is zero, widened by the bias random walk
/// over the window,
///   sigma^2 = sigma_sample^2 / samples + sigma_walk^2 window_s,
///   sigma_sample^2 = density^2 / nominal_dt_s (ImuNoise: one reading's discrete variance),
/// so the prior only holds what the window cannot tell (e.g. a horizontal b_a against a tilt of
/// gravity when the body does not turn) and never pins an observable bias. samples = 0: no prior.
struct BiasPriorInformation {
  double gyro = 0.0;  ///< 1/(rad/s)^2
  double acc = 0.0;   ///< 1/(m/s^2)^2
};
BiasPriorInformation biasPriorInformation(const imu::ImuNoise& noise, double window_s, double samples);

/// Inertial-only initialisation with known (fixed) keyframe poses: velocities, one bias pair for the
/// window and the gravity direction R_w_g (g_w = R_w_g (0, 0, -G)); scale is known (RGB-D).
struct ImuInitProblem {
  std::vector<SE3> T_w_b;  ///< keyframe poses in the (not gravity-aligned) map frame w
  /// pims[k]: keyframe k -> k + 1 (size T_w_b.size() - 1).
  std::vector<std::shared_ptr<const imu::Preintegrated>> pims;
  imu::ImuBias bias_init;
  double gravity_m_s2 = imu::kGravity_m_s2;
  /// Per-axis information of the priors on the biases (biasPriorInformation), zero-mean but for
  /// the gyro's when gyro_bias_prior_mean is set (a rest's mean reading).
  double gyro_bias_prior_information = 1e2;
  Vec3 gyro_bias_prior_mean = Vec3::Zero();
  double acc_bias_prior_information = 1e2;
  int iterations = 20;
  /// Gravity already known (a loaded map's, estimated over a longer window): R_w_g held at it, so
  /// the window only estimates velocities and biases (a horizontal b_a no longer trades with a tilt).
  std::optional<Mat3> known_R_w_g;
};

struct ImuInitResult {
  Mat3 R_w_g = Mat3::Identity();
  Vec3 g_w = Vec3::Zero();
  imu::ImuBias bias;
  std::vector<Vec3> v_w_b;  ///< per keyframe
  sparse_opt::Summary summary;
  /// inertialAccelerationCovariance at the result ((m/s^2)^2, world frame; infinite if singular).
  Mat3 acceleration_covariance_w = Mat3::Zero();
};

/// Linear first guess: velocities and g_w by least squares on the velocity and position equations
/// with the biases of the preintegrations; then R_w_g from the direction of g_w.
ImuInitResult linearImuInit(const ImuInitProblem& problem);

/// The linear guess refined by the inertial-only optimisation (EdgeInertialGravity).
ImuInitResult initializeImu(const ImuInitProblem& problem);

/// Posterior covariance ((m/s^2)^2, world frame) of the acceleration an IMU prediction integrates,
/// from the inertial-only problem's information at `estimate` (poses held): the joint (b_a, gravity
/// direction) block of H^-1 mapped through -R_w_b(newest) db_a + dg_w/dtheta dtheta (a_w = R_w_b (f - b_a) + g_w). A tilt of
/// gravity and a horizontal bias trade off, so only the joint block says how well the world
/// acceleration is known; it shrinks as the window grows and turns (Campos et al. 2021 §V-B's
/// problem, read as a Gaussian posterior). Infinite entries when the information is singular.
Mat3 inertialAccelerationCovariance(const ImuInitProblem& problem, const ImuInitResult& estimate);

/// Largest standard deviation of an acceleration covariance (m/s^2): sqrt of its largest
/// eigenvalue; infinity when the covariance is not finite.
double accelerationSigma(const Mat3& covariance_w);

}  // namespace ltlo::optim
