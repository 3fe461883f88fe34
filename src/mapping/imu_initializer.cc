#include "imu_initializer.h"

#include "ltlo/core/assert.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/optim/bundle_adjust.h"

namespace ltlo::mapping {

ImuChain imuChainEndingAt(const map::Map& map, const std::shared_ptr<map::KeyFrame>& newest) {
  ImuChain chain;
  if (!newest || newest->isBad()) return chain;
  std::vector<std::shared_ptr<map::KeyFrame>> reversed{newest};
  std::vector<std::shared_ptr<const imu::Preintegrated>> reversed_pims;
  std::shared_ptr<map::KeyFrame> current = newest;
  while (true) {
    const std::optional<imu::Preintegrated> pim = current->imuFromPrevious();
    const std::shared_ptr<map::KeyFrame> previous = map.keyFrame(current->previousKeyFrame());
    if (!pim || !previous || previous->isBad() || pim->dt_s() <= 0.0) break;
    reversed_pims.push_back(std::make_shared<const imu::Preintegrated>(*pim));
    reversed.push_back(previous);
    current = previous;
  }
  chain.keyframes.assign(reversed.rbegin(), reversed.rend());
  chain.pims.assign(reversed_pims.rbegin(), reversed_pims.rend());
  return chain;
}

std::optional<ImuInitEstimate> initialiseImuOnChain(const ImuChain& chain, const ImuInitOptions& options,
                                                    const imu::ImuBias& bias_init) {
  LTLO_ASSERT(chain.keyframes.size() >= 3 && chain.pims.size() + 1 == chain.keyframes.size(),
              "IMU initialisation on a chain of " << chain.keyframes.size() << " keyframes and "
                                                  << chain.pims.size() << " preintegrations");
  optim::ImuInitProblem problem;
  for (const std::shared_ptr<map::KeyFrame>& kf : chain.keyframes) problem.T_w_b.push_back(kf->T_w_b());
  problem.pims = chain.pims;
  problem.bias_init = bias_init;
  problem.gyro_bias_prior_information = options.prior_gyro_bias;
  problem.acc_bias_prior_information = options.prior_acc_bias;
  problem.iterations = options.iterations;
  const optim::ImuInitResult result = optim::initializeImu(problem);
  bool finite = result.g_w.allFinite() && result.bias.b_g.allFinite() && result.bias.b_a.allFinite();
  for (const Vec3& v : result.v_w_b) finite = finite && v.allFinite();
  if (!finite) return std::nullopt;
  for (std::size_t k = 0; k < chain.keyframes.size(); ++k) {
    if (chain.keyframes[k]->isBad()) continue;
    chain.keyframes[k]->setVelocity(result.v_w_b[k]);
    chain.keyframes[k]->setBias(result.bias);
  }
  ImuInitEstimate estimate;
  estimate.g_w = result.g_w;
  estimate.bias = result.bias;
  estimate.keyframes = static_cast<int>(chain.keyframes.size());
  estimate.span_s = chain.span_s();
  estimate.final_chi2 = result.summary.final_chi2;
  return estimate;
}

void predictInertialState(const map::Map& map, map::KeyFrame& kf, const Vec3& g_w) {
  const std::shared_ptr<map::KeyFrame> previous = map.keyFrame(kf.previousKeyFrame());
  const std::optional<imu::Preintegrated> pim = kf.imuFromPrevious();
  if (!previous || previous->isBad() || !pim) return;
  const imu::ImuBias previous_bias = previous->bias();
  const imu::ImuBias bias = kf.bias();
  if (bias.b_g.isZero() && bias.b_a.isZero()) kf.setBias(previous_bias);
  if (!kf.v_w_b().isZero()) return;
  imu::NavState state_i;
  const SE3 T_w_b_i = previous->T_w_b();
  state_i.R_w_b = T_w_b_i.rotationMatrix();
  state_i.p_w_b = T_w_b_i.translation();
  state_i.v_w_b = previous->v_w_b();
  kf.setVelocity(imu::predict(state_i, *pim, previous_bias, g_w).v_w_b);
}

}  // namespace ltlo::mapping
