#pragma once
/// How sequence readers treat imperfect input (YAML keys Sequence.*).
#include <string>

namespace ltlo {

class SettingsFile;

enum class ImuGapPolicy { kWarn, kFail };

struct SequenceOptions {
  double max_imu_gap_s = 0.05;                 ///< Sequence.MaxImuGap (s): longer gaps are reported
  ImuGapPolicy imu_gap_policy = ImuGapPolicy::kWarn;  ///< Sequence.ImuGapPolicy: "warn" or "fail"

  /// Reads the optional Sequence.* keys (defaults above when absent); throws ConfigError.
  static SequenceOptions load(const SettingsFile& file);
};

}  // namespace ltlo
