#pragma once
/// A surfel of the offline static-background model (ElasticFusion-style; Keller et al. 2013,
/// Whelan et al. 2015): an oriented disc with colour, confidence and the times it was seen.
#include <Eigen/Core>
#include <cstdint>

namespace ltlo::recon {

/// All geometry in the world frame w of the trajectory the surfels were fused with (metres).
struct Surfel {
  Eigen::Vector3f position_w = Eigen::Vector3f::Zero();
  float radius_m = 0.0f;                                ///< disc radius
  Eigen::Vector3f normal_w = Eigen::Vector3f::UnitZ();  ///< unit, towards the observing cameras
  /// Sum of the radial weights alpha of the fused measurements; negative marks a removed surfel
  /// inside the fusion (never in a returned set).
  float confidence = 0.0f;
  Eigen::Vector3f colour_rgb = Eigen::Vector3f::Zero();  ///< 0..255
  float first_seen_s = 0.0f;  ///< creation time, s after the first fused frame
  float last_seen_s = 0.0f;   ///< time of the last fused measurement, same clock
  /// Free-space violations (the measured surface lay behind it) minus later confirmations, >= 0.
  uint16_t violations = 0;
};

}  // namespace ltlo::recon
