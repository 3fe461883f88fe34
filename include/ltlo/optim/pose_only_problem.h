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

/// Gaussian prior on the previous frame's state from its own (marginalised) optimisation, as a
/// block-diagonal information in the vertex perturbations of vertices.h. With it the previous state
/// is optimised together with the current one instead of held fixed (ORB-SLAM3's tracking against
/// the last frame).
struct PreviousStatePrior {
  Mat6 pose_information = Mat6::Identity();      ///< [dphi; drho] of T_w_b_prev
  Mat3 velocity_information = Mat3::Identity();  ///< (m/s)^-2
  Mat3 gyro_bias_information = Mat3::Identity(); ///< (rad/s)^-2
  Mat3 acc_bias_information = Mat3::Identity();  ///< (m/s^2)^-2
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
  /// Current-frame information of [dphi; drho] (VertexPose) from the last round's inliers, e.g.
  /// the prior of the next pose-only problem (PreviousStatePrior::pose_information). Zero when the pose
  /// is not constrained (too few inliers without IMU).
  Mat6 pose_information = Mat6::Zero();
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

}  // namespace ltlo::optim
