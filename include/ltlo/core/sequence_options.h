#pragma once
/// How sequence readers treat imperfect input (YAML keys Sequence.*).
#include <string>

namespace ltlo {

class SettingsFile;

enum class ImuGapPolicy { kWarn, kFail };

struct SequenceOptions {
  double max_imu_gap_s = 0.05;                 ///< Sequence.MaxImuGap (s): longer gaps are reported
  ImuGapPolicy imu_gap_policy = ImuGapPolicy::kWarn;  ///< Sequence.ImuGapPolicy: "warn" or "fail"
  /// Sequence.MaxImuReorder (s), [0, 10]: IMU samples whose stamp goes back by at most this much
  /// behind the latest stamp before them are put in time order (with one warning per file); a
  /// larger jump back (a clock reset, two files joined) is an error.
  double max_imu_reorder_s = 0.1;

  /// Reads the optional Sequence.* keys (defaults above when absent); throws ConfigError.
  static SequenceOptions load(const SettingsFile& file);
};

}  // namespace ltlo
