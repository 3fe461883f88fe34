#pragma once
/// Pose-only optimisation for tracking (namespace ltlo::optim): the current body pose (and, with an
/// IMU, its velocity and biases) against fixed map points, with rounds of optimise-and-reject-outliers
/// (chi-square 95% tests, Huber kernels of delta sqrt(7.815) for RGB-D and sqrt(5.991) for 2-D
/// observations, the kernel dropped in the last round). Plain inputs and outputs: no map types.
#include <memory>
#include <optional>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/optim/inertial_edges.h"
#include "ltlo/optim/reprojection_edges.h"

namespace ltlo::optim {

/// One keypoint matched to a fixed map point.
struct PoseObservation {
  Vec3 p_w = Vec3::Zero();     ///< map point in world (m)
  Vec2 uv = Vec2::Zero();      ///< keypoint (px)
  double depth_m = 0.0;        ///< measured depth (m); <= 0: no depth, a monocular 2-D edge
  double sigma_px = 1.0;       ///< keypoint standard deviation (px), e.g. the pyramid scale
  double static_weight = 1.0;  ///< beta * gamma (thesis Eq. 53), 1 for a static point
};

/// Gaussian prior on the previous frame's state from its own optimisation (ORB-SLAM3's tracking
/// against the last frame): the marginal information of [dphi; drho; dv; db_g; db_a] (the
/// perturbations of VertexPose, VertexVelocity, VertexGyroBias, VertexAccBias, in that order) at
/// the InertialLink's previous state, e.g. PoseOnlyResult::state_information of the previous
/// frame or predictedStateInformation() of a predicted one. With it the previous state is
/// optimised together with the current one instead of held fixed.
struct PreviousStatePrior {
  Mat15 information = Mat15::Identity();
};

/// The previous frame's state and the IMU preintegrated from it to the current frame. The previous
/// state is held fixed unless a prior is given.
struct InertialLink {
  SE3 T_w_b_prev;
  Vec3 v_w_b_prev = Vec3::Zero();
  imu::ImuBias bias_prev;
  std::shared_ptr<const imu::Preintegrated> pim;  ///< previous -> current frame
  Vec3 g_w = imu::gravityWorld();
  double lambda_imu = 1.0;  ///< weight of the bias random walk (thesis Eq. 58)
  std::optional<PreviousStatePrior> prev_prior;  ///< absent: previous state fixed
  /// With the previous state fixed (no prior): leave its velocity free, without a prior (a keyframe
  /// whose velocity is not known yet: the inertial edge then estimates it from the two poses).
  bool prev_velocity_free = false;
  /// With prev_velocity_free: a Gaussian prior on that velocity at v_w_b_prev with this
  /// information, (m/s)^-2 (e.g. a new map's first keyframe whose velocity the IMU carried through a
  /// loss: known to its dead reckoning's uncertainty, neither exactly nor not at all). Absent: free.
  std::optional<Mat3> prev_velocity_information;
};

struct PoseOnlyProblem {
  ProjectionModel model;         ///< T_c_x = T_c_b, bf for the RGB-D edges
  SE3 T_w_b_init;                ///< initial guess (IMU prediction or constant velocity)
  Vec3 v_w_b_init = Vec3::Zero();
  imu::ImuBias bias_init;
  std::vector<PoseObservation> observations;
  std::optional<InertialLink> inertial;  ///< absent: vision-only (pose vertex only)
};

struct PoseOnlyOptions {
  int rounds = 4;                 ///< optimise-and-reject rounds (ORB-SLAM: 4)
  int iterations_per_round = 10;  ///< LM iterations per round
  double chi2_2d = kChi2Threshold2Dof;
  double chi2_3d = kChi2Threshold3Dof;
  int num_threads = 1;
};

struct PoseOnlyResult {
  SE3 T_w_b;
  /// Marginal information of the current pose [dphi; drho] (VertexPose) from the last round's
  /// inliers (and, with the IMU, everything else marginalised out). Zero when the pose is not
  /// constrained (too few inliers without IMU).
  Mat6 pose_information = Mat6::Zero();
  /// With the IMU: marginal information of the whole current state [dphi; drho; dv; db_g; db_a]
  /// at the result, the previous state marginalised out (the Schur complement of the final
  /// Hessian of the inlier, inertial, bias-walk and prior edges): the PreviousStatePrior of the
  /// next frame's problem. Zero without the IMU.
  Mat15 state_information = Mat15::Zero();
  Vec3 v_w_b = Vec3::Zero();
  imu::ImuBias bias;
  std::vector<bool> inliers;  ///< per observation, in input order
  int num_inliers = 0;
  double final_chi2 = 0.0;    ///< robust chi2 of the last round
};

/// Optimises the current state. An observation is an outlier in a round when its unweighted chi2
/// (observation information, without the static weight) exceeds the threshold of its dimension or
/// its point is behind the camera; outliers are left out of the next round but re-tested after it.
PoseOnlyResult optimizePose(const PoseOnlyProblem& problem, const PoseOnlyOptions& options = PoseOnlyOptions());

/// Information of a current state predicted through `link` alone (no observations): the previous
/// state's prior (or the previous state held fixed) pushed through the inertial and bias-walk
/// edges and marginalised, linearised at `current` (normally imu::predict of the previous state,
/// where the inertial residual vanishes). The inverse covariance of an IMU-only prediction, e.g.
/// of a frame while tracking is lost; equal to optimizePose's state_information with no
/// observations.
Mat15 predictedStateInformation(const InertialLink& link, const InertialState& current);

/// Marginal information of the first `keep` coordinates of an information matrix (Schur
/// complement of the others): e.g. the pose block of a state information. The marginalised block
/// must be positive definite; a symmetric result.
MatX marginalInformation(const MatX& information, int keep);

}  // namespace ltlo::optim
