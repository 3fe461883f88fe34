#pragma once
/// IMU initialisation of local mapping (private to ltlo_mapping): inertial-only optimisation of
/// velocities, one bias pair and the gravity direction over the keyframes' IMU chain with their
/// (fixed) poses; scale is known from depth, and the map is not rotated (g_w in the map frame).
#include <memory>
#include <optional>
#include <vector>

#include "ltlo/core/settings.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/map.h"

namespace ltlo::mapping {

/// Keyframes in time order linked by preintegrations: pims[k] goes from keyframes[k] to k + 1.
struct ImuChain {
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;
  std::vector<std::shared_ptr<const imu::Preintegrated>> pims;
  double span_s() const { return keyframes.empty() ? 0.0 : keyframes.back()->t_s() - keyframes.front()->t_s(); }
};

/// The chain ending at `newest`, followed back through previousKeyFrame() while each link has a
/// preintegration and the keyframe is live.
ImuChain imuChainEndingAt(const map::Map& map, const std::shared_ptr<map::KeyFrame>& newest);

struct ImuInitEstimate {
  Vec3 g_w = Vec3::Zero();
  imu::ImuBias bias;
  int keyframes = 0;
  double span_s = 0.0;
  double final_chi2 = 0.0;
};

/// Runs optim::initializeImu on `chain` from `bias_init` (priors and iterations from `options`) and,
/// on a finite result, sets every chain keyframe's velocity and bias. nullopt on a non-finite result.
std::optional<ImuInitEstimate> initialiseImuOnChain(const ImuChain& chain, const ImuInitOptions& options,
                                                    const imu::ImuBias& bias_init);

/// Velocity (and, when it is still zero, bias) of a keyframe inserted after the initialisation,
/// predicted from its predecessor through the preintegration when tracking left it at zero.
void predictInertialState(const map::Map& map, map::KeyFrame& kf, const Vec3& g_w);

}  // namespace ltlo::mapping
