#include "ltlo/render/look_at.h"

namespace ltlo::render {

SE3 lookAt(const Vec3& eye_w, const Vec3& target_w, const Vec3& up_w) {
  const Vec3 z = (target_w - eye_w).normalized();
  Vec3 y = -(up_w - z * z.dot(up_w));  // image down
  if (y.norm() < 1e-9) y = z.unitOrthogonal();
  y.normalize();
  const Vec3 x = y.cross(z);
  Mat3 R_w_c;
  R_w_c.col(0) = x;
  R_w_c.col(1) = y;
  R_w_c.col(2) = z;
  return SE3(R_w_c, eye_w).inverse();
}

}  // namespace ltlo::render
