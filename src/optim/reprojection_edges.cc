#include "ltlo/optim/reprojection_edges.h"

#include <cmath>

namespace ltlo::optim {

double huberLoss(double squared_norm, double delta) {
  if (squared_norm <= delta * delta) return squared_norm;
  return 2.0 * delta * std::sqrt(squared_norm) - delta * delta;
}

double staticWeightedCost(double beta, double gamma, double r_sq, double c_hat, double huber_delta) {
  const double static_part = beta * beta * gamma * gamma * huberLoss(r_sq, huber_delta);
  const double dynamic_part =
      (1.0 - beta) * (1.0 - beta) * (1.0 - gamma) * (1.0 - gamma) * huberLoss(c_hat, huber_delta);
  return static_part + dynamic_part;
}

Vec3 ProjectionModel::projectRgbd(const Vec3& p_c) const {
  const Vec2 uv = camera.project(p_c);
  return Vec3(uv.x(), uv.y(), uv.x() - bf_px_m / p_c.z());
}

Mat3 ProjectionModel::projectRgbdJacobian(const Vec3& p_c) const {
  const Mat23 J_uv = camera.projectJacobian(p_c);
  Mat3 J;
  J.topRows<2>() = J_uv;
  J.row(2) = J_uv.row(0);
  J(2, 2) += bf_px_m / (p_c.z() * p_c.z());
  return J;
}

}  // namespace ltlo::optim
