#include <gtest/gtest.h>

#include "ltlo/core/lie.h"

namespace ltlo {
namespace {

TEST(So3, ExpLogRoundTrip) {
  for (const double angle : {0.0, 1e-9, 1e-4, 0.5, 3.0, M_PI - 1e-7}) {
    const Vec3 phi = angle * Vec3(1.0, -2.0, 0.5).normalized();
    EXPECT_LT((so3Log(so3Exp(phi)) - phi).norm(), 1e-9) << angle;
  }
}

}  // namespace
}  // namespace ltlo
