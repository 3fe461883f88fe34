// The IMU term handed to the dense solve (issue 11): its previous state must be the one the
// prediction came from, so that the image term sees the frame-to-frame motion even when the
// tracker predicted from a keyframe that local mapping moved after the previous frame was tracked.
#include "ltlo/tracking/dense_segmenter.h"

#include <gtest/gtest.h>

#include "ltlo/core/lie.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/imu/preintegration.h"

namespace ltlo::tracking {
namespace {

constexpr double kDt = 1.0 / 30.0;

struct ImuMotion {
  imu::Preintegrated pim{imu::ImuBias{}, imu::ImuNoise{}};
  imu::ImuBias bias;
  Vec3 g_w{0.0, 0.0, -9.81};

  ImuMotion() {
    bias.b_g = Vec3(0.002, -0.001, 0.003);  // estimated bias, different from the linearisation point
    bias.b_a = Vec3(0.02, 0.01, -0.03);
    constexpr int kSteps = 7;
    for (int k = 0; k < kSteps; ++k) {
      pim.integrateStep(Vec3(0.3, -0.2, 0.5), Vec3(0.4, -0.3, 9.9), kDt / kSteps);
    }
  }
  imu::NavState predict(const imu::NavState& previous) const { return imu::predict(previous, pim, bias, g_w); }
};

MotionPrior imuPrior(const ImuMotion& motion, const imu::NavState& previous_held, const imu::NavState& predicted) {
  MotionPrior prior;
  prior.kind = MotionPrior::Kind::kImu;
  prior.dt_s = kDt;
  prior.T_w_b_prev = SE3(Quat(previous_held.R_w_b), previous_held.p_w_b);
  prior.v_w_b_prev = previous_held.v_w_b;
  prior.bias_prev = motion.bias;
  prior.T_w_b_pred = SE3(Quat(predicted.R_w_b), predicted.p_w_b);
  prior.v_w_b_pred = predicted.v_w_b;
  prior.pim = std::make_shared<const imu::Preintegrated>(motion.pim);
  prior.g_w = motion.g_w;
  return prior;
}

imu::NavState state(const Vec3& rotation_vector, const Vec3& p_w_b, const Vec3& v_w_b) {
  imu::NavState s;
  s.R_w_b = SE3::exp((Vec6() << 0.0, 0.0, 0.0, rotation_vector).finished()).rotationMatrix();
  s.p_w_b = p_w_b;
  s.v_w_b = v_w_b;
  return s;
}

void expectStateNear(const segmentation::DensePrior& out, const imu::NavState& expected) {
  EXPECT_LT((out.T_w_b_prev.translation() - expected.p_w_b).norm(), 1e-9);
  EXPECT_LT(so3Log(out.T_w_b_prev.rotationMatrix().transpose() * expected.R_w_b).norm(), 1e-9);
  EXPECT_LT((out.v_w_b_prev - expected.v_w_b).norm(), 1e-9);
}

TEST(DensePrior, ImuPreviousStateIsTheTrackedOneWithoutMapCorrection) {
  const ImuMotion motion;
  const imu::NavState previous = state(Vec3(0.1, -0.4, 1.2), Vec3(1.0, 2.0, 0.5), Vec3(0.3, -0.1, 0.05));
  const segmentation::DensePrior out = densePrior(imuPrior(motion, previous, motion.predict(previous)), DenseOptions());
  EXPECT_EQ(out.kind, segmentation::DensePrior::Kind::kImu);
  expectStateNear(out, previous);
}

// Local mapping moved the last keyframe by 8 cm and 2 deg after the previous frame was tracked;
// the tracker predicts from the corrected keyframe. The previous state of the IMU term moves with
// the correction: the prediction minus this frame's preintegrated motion, not the stale pose.
TEST(DensePrior, ImuPreviousStateFollowsAMapCorrection) {
  const ImuMotion motion;
  const imu::NavState stale = state(Vec3(0.1, -0.4, 1.2), Vec3(1.0, 2.0, 0.5), Vec3(0.3, -0.1, 0.05));
  const imu::NavState corrected = state(Vec3(0.1, -0.4, 1.235), Vec3(1.08, 1.99, 0.51), Vec3(0.32, -0.1, 0.04));
  const segmentation::DensePrior out = densePrior(imuPrior(motion, stale, motion.predict(corrected)), DenseOptions());
  expectStateNear(out, corrected);
  EXPECT_GT((out.T_w_b_prev.translation() - stale.p_w_b).norm(), 0.07);
}

}  // namespace
}  // namespace ltlo::tracking
