#pragma once
/// Reprojection edges (namespace ltlo::optim): RGB-D "stereo-like" 3-D observations [u, v, u_r] and
/// monocular 2-D observations [u, v], each with a point vertex (bundle adjustment) or with the point
/// fixed inside the edge (pose-only tracking), each over a body pose (VertexPose, with the fixed
/// extrinsic T_b_c) or a camera pose (VertexCameraPose, vision-only problems).
///
/// RGB-D observation: a keypoint (u, v) with metric depth d becomes [u, v, u_r], u_r = u - bf / d,
/// where bf = fx * virtual_baseline_m (px m) is the camera's virtual stereo baseline (ORB-SLAM's
/// RGB-D convention: the depth error is then a pixel error that grows like d^2, as a stereo rig's).
/// Residual r = observation - prediction (thesis Eq. 52), with
///   prediction(p_c) = [fx x/z + cx, fy y/z + cy, fx x/z + cx - bf/z],  p_c = T_c_x * p_x,
/// where p_x is the point in the pose vertex's frame (body or camera, see vertices.h).
///
/// Static weight (thesis Eq. 53): for fixed static weights beta (map point) and gamma (cluster), the
/// state optimisation sees (beta gamma)^2 rho_H(|r|^2); the second term of Eq. 53 is constant in the
/// state. setStaticWeight(w = beta * gamma) makes w^2 the edge's cost scale
/// (sparse_opt::EdgeBase::setCostScale), so the robust kernel acts on the unweighted |r|^2 = r^T
/// Omega r (its threshold stays where the noise puts it) and the edge contributes w^2 rho_H(|r|^2),
/// exactly the first term of Eq. 53.
#include <sparse_opt/edge.h>

#include "ltlo/core/camera.h"
#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/optim/vertices.h"

namespace ltlo::optim {

/// Huber loss on a squared norm s: s for s <= delta^2, 2 delta sqrt(s) - delta^2 beyond
/// (sparse_opt::HuberKernel's rho).
double huberLoss(double squared_norm, double delta);

/// The thesis' robust residual (Eq. 53) of one observation:
///   rho = beta^2 gamma^2 rho_H(r_sq) + (1 - beta)^2 (1 - gamma)^2 rho_H(c_hat),
/// r_sq = |r|^2 (Mahalanobis, the edge's unweightedChi2()), c_hat = mean of |r|^2 over all
/// observations, rho_H the Huber loss of threshold huber_delta.
double staticWeightedCost(double beta, double gamma, double r_sq, double c_hat, double huber_delta);

/// Chi-square 95% thresholds used for outlier rejection and as squared Huber deltas.
constexpr double kChi2Threshold2Dof = 5.991;
constexpr double kChi2Threshold3Dof = 7.815;

/// Camera model shared by the reprojection edges.
struct ProjectionModel {
  PinholeCamera camera;
  /// T_c_x: from the pose vertex's frame into the camera. T_c_b (inverse of ImuCalib::T_b_c) for
  /// VertexPose, identity for VertexCameraPose.
  SE3 T_c_x;
  /// bf = fx * virtual baseline (px m); only the RGB-D edges use it.
  double bf_px_m = 0.0;

  /// [u, v] of a camera-frame point.
  Vec2 project(const Vec3& p_c) const { return camera.project(p_c); }
  /// [u, v, u - bf / z] of a camera-frame point.
  Vec3 projectRgbd(const Vec3& p_c) const;
  /// d projectRgbd / d p_c (3x3).
  Mat3 projectRgbdJacobian(const Vec3& p_c) const;
  /// The RGB-D observation of keypoint `uv` with metric depth depth_m: [u, v, u - bf / depth_m].
  Vec3 rgbdObservation(const Vec2& uv, double depth_m) const {
    return Vec3(uv.x(), uv.y(), uv.x() - bf_px_m / depth_m);
  }
};

/// An edge whose cost is w^2 rho(r^T Omega r) for a static weight w = beta * gamma (file comment).
template <typename Base>
class StaticWeighted : public Base {
 public:
  using typename Base::InformationMatrix;
  /// Information of the observation (e.g. I / sigma_px^2); the static weight does not change it.
  void setObservationInformation(const InformationMatrix& info) { this->setInformation(info); }
  /// w in [0, 1]: the edge's cost (kernel included) is scaled by w^2.
  void setStaticWeight(double weight) {
    weight_ = weight;
    this->setCostScale(weight * weight);
  }
  double staticWeight() const { return weight_; }
  const InformationMatrix& observationInformation() const { return this->information(); }
  /// r^T Omega r without the static weight at the last evaluation (the |r|^2 of Eq. 53).
  double unweightedChi2() const { return this->error().dot(this->information() * this->error()); }

 private:
  double weight_ = 1.0;
};

/// RGB-D reprojection between a pose vertex and a map point. Measurement [u, v, u_r] (px).
template <typename PoseVertex>
class EdgeRgbdReprojection final
    : public StaticWeighted<sparse_opt::BaseEdge<3, Vec3, PoseVertex, VertexPoint>> {
 public:
  explicit EdgeRgbdReprojection(const ProjectionModel& model) : model_(model) {}
  void computeError() override {
    p_x_ = PoseVertex::pointInFrame(this->template estimate<0>(), this->template estimate<1>());
    p_c_ = model_.T_c_x * p_x_;
    this->error_ = this->measurement_ - model_.projectRgbd(p_c_);
  }
  /// At the estimates of the last computeError() (sparse_opt's contract): its p_x and p_c.
  void linearizeOplus() override {
    const SE3& T = this->template estimate<0>();
    const Mat3 d_r_d_p_x = -model_.projectRgbdJacobian(p_c_) * model_.T_c_x.rotationMatrix();
    // A fixed pose's block is never read (local BA's fixed keyframes: about half the edges).
    if (!this->vertex(0)->fixed()) this->template jacobian<0>() = d_r_d_p_x * PoseVertex::d_point_d_delta(T, p_x_);
    this->template jacobian<1>() = d_r_d_p_x * PoseVertex::d_point_d_world(T);
  }
  /// The point lies in front of the camera.
  bool isDepthPositive() const { return cameraPoint().z() > 0.0; }
  Vec3 cameraPoint() const {
    return model_.T_c_x * PoseVertex::pointInFrame(this->template estimate<0>(), this->template estimate<1>());
  }

 private:
  ProjectionModel model_;
  Vec3 p_x_ = Vec3::Zero();  ///< the point in the pose's frame at the last computeError()
  Vec3 p_c_ = Vec3::Zero();  ///< and in the camera frame
};

/// Monocular reprojection between a pose vertex and a map point. Measurement [u, v] (px).
template <typename PoseVertex>
class EdgeMonoReprojection final
    : public StaticWeighted<sparse_opt::BaseEdge<2, Vec2, PoseVertex, VertexPoint>> {
 public:
  explicit EdgeMonoReprojection(const ProjectionModel& model) : model_(model) {}
  void computeError() override { this->error_ = this->measurement_ - model_.project(cameraPoint()); }
  void linearizeOplus() override {
    const SE3& T = this->template estimate<0>();
    const Vec3 p_x = PoseVertex::pointInFrame(T, this->template estimate<1>());
    const Mat23 d_r_d_p_x =
        -model_.camera.projectJacobian(model_.T_c_x * p_x) * model_.T_c_x.rotationMatrix();
    if (!this->vertex(0)->fixed()) this->template jacobian<0>() = d_r_d_p_x * PoseVertex::d_point_d_delta(T, p_x);
    this->template jacobian<1>() = d_r_d_p_x * PoseVertex::d_point_d_world(T);
  }
  bool isDepthPositive() const { return cameraPoint().z() > 0.0; }
  Vec3 cameraPoint() const {
    return model_.T_c_x * PoseVertex::pointInFrame(this->template estimate<0>(), this->template estimate<1>());
  }

 private:
  ProjectionModel model_;
};

/// RGB-D reprojection of a fixed world point p_w (pose-only tracking). Measurement [u, v, u_r].
template <typename PoseVertex>
class EdgeRgbdReprojectionPoseOnly final
    : public StaticWeighted<sparse_opt::BaseEdge<3, Vec3, PoseVertex>> {
 public:
  EdgeRgbdReprojectionPoseOnly(const ProjectionModel& model, const Vec3& p_w) : model_(model), p_w_(p_w) {}
  void computeError() override {
    this->error_ = this->measurement_ - model_.projectRgbd(cameraPoint());
  }
  void linearizeOplus() override {
    const SE3& T = this->template estimate<0>();
    const Vec3 p_x = PoseVertex::pointInFrame(T, p_w_);
    this->template jacobian<0>() = -model_.projectRgbdJacobian(model_.T_c_x * p_x) *
                                   model_.T_c_x.rotationMatrix() * PoseVertex::d_point_d_delta(T, p_x);
  }
  bool isDepthPositive() const { return cameraPoint().z() > 0.0; }
  Vec3 cameraPoint() const { return model_.T_c_x * PoseVertex::pointInFrame(this->template estimate<0>(), p_w_); }
  const Vec3& pointWorld() const { return p_w_; }

 private:
  ProjectionModel model_;
  Vec3 p_w_;
};

/// Monocular reprojection of a fixed world point p_w (pose-only tracking). Measurement [u, v].
template <typename PoseVertex>
class EdgeMonoReprojectionPoseOnly final
    : public StaticWeighted<sparse_opt::BaseEdge<2, Vec2, PoseVertex>> {
 public:
  EdgeMonoReprojectionPoseOnly(const ProjectionModel& model, const Vec3& p_w) : model_(model), p_w_(p_w) {}
  void computeError() override { this->error_ = this->measurement_ - model_.project(cameraPoint()); }
  void linearizeOplus() override {
    const SE3& T = this->template estimate<0>();
    const Vec3 p_x = PoseVertex::pointInFrame(T, p_w_);
    this->template jacobian<0>() = -model_.camera.projectJacobian(model_.T_c_x * p_x) *
                                   model_.T_c_x.rotationMatrix() * PoseVertex::d_point_d_delta(T, p_x);
  }
  bool isDepthPositive() const { return cameraPoint().z() > 0.0; }
  Vec3 cameraPoint() const { return model_.T_c_x * PoseVertex::pointInFrame(this->template estimate<0>(), p_w_); }
  const Vec3& pointWorld() const { return p_w_; }

 private:
  ProjectionModel model_;
  Vec3 p_w_;
};

}  // namespace ltlo::optim
