#include "ltlo/core/sequence_options.h"

#include "ltlo/core/settings_file.h"

namespace ltlo {

SequenceOptions SequenceOptions::load(const SettingsFile& file) {
  SequenceOptions options;
  options.max_imu_gap_s = file.getDouble("Sequence.MaxImuGap", options.max_imu_gap_s, 1e-4, 10.0);
  const std::string policy = file.getString("Sequence.ImuGapPolicy", "warn");
  if (policy == "warn") {
    options.imu_gap_policy = ImuGapPolicy::kWarn;
  } else if (policy == "fail") {
    options.imu_gap_policy = ImuGapPolicy::kFail;
  } else {
    file.fail("Sequence.ImuGapPolicy", "\"" + policy + "\"", "\"warn\" or \"fail\"");
  }
  options.max_imu_reorder_s =
      file.getDouble("Sequence.MaxImuReorder", options.max_imu_reorder_s, 0.0, 10.0);
  return options;
}

}  // namespace ltlo
