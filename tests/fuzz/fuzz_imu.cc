// libFuzzer target: the IMU readers, each input read as imu.txt (seconds, spaces, half rows of
// one sensor), as EuRoC imu0/data.csv (nanoseconds, commas) and, cut at the line nearest its
// middle, as OpenLORIS accel.txt + gyro.txt, with both gap policies and two reorder limits; the
// samples read are then cut into per-frame intervals as the sequence reader does. Bad lines must
// give InputError.
#include <cstddef>
#include <cstdint>
#include <sstream>

#include "fuzz_common.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/imu_sample.h"
#include "parsers.h"

namespace {

void cutIntoFrames(const ltlo::ImuSamples& samples) {
  if (samples.empty()) return;
  const double t0_s = samples.front().t_s;
  const double t1_s = samples.back().t_s;
  // Ten frame intervals over the stream and one on each side of it.
  const double step_s = (t1_s - t0_s) / 10.0;
  for (int k = -1; k <= 11; ++k) {
    (void)ltlo::imuSamplesBetween(samples, t0_s + k * step_s, t0_s + (k + 1) * step_s);
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  ltlo::fuzz::quietLogging();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = ltlo::fuzz::asText(data, size);
  const size_t middle = text.find('\n', text.size() / 2);
  const std::string first_half = middle == std::string::npos ? text : text.substr(0, middle + 1);
  const std::string second_half = middle == std::string::npos ? text : text.substr(middle + 1);
  for (const ltlo::ImuGapPolicy policy : {ltlo::ImuGapPolicy::kWarn, ltlo::ImuGapPolicy::kFail}) {
    ltlo::SequenceOptions options;
    options.imu_gap_policy = policy;
    options.max_imu_reorder_s = policy == ltlo::ImuGapPolicy::kWarn ? 0.1 : 0.0;
    try {
      std::istringstream in(text);
      cutIntoFrames(ltlo::io::detail::parseImuText(in, "SEQ/imu.txt", options));
    } catch (const ltlo::InputError&) {
    }
    try {
      std::istringstream in(text);
      cutIntoFrames(ltlo::io::detail::parseEurocImuCsv(in, "SEQ/imu0/data.csv", options));
    } catch (const ltlo::InputError&) {
    }
    try {
      std::istringstream accel(first_half);
      std::istringstream gyro(second_half);
      cutIntoFrames(ltlo::io::detail::parseOpenLorisImu(accel, "SEQ/accel.txt", gyro, "SEQ/gyro.txt",
                                                        options));
    } catch (const ltlo::InputError&) {
    }
  }
  return 0;
}
