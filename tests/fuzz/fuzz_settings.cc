// libFuzzer target: the settings / calibration YAML loader (SettingsFile on OpenCV FileStorage,
// every option table of Settings::load, SensorCalib). Bad files must give ConfigError or
// InputError; anything else (a crash, another exception, a sanitizer report) is a finding.
#include <cstddef>
#include <cstdint>

#include "fuzz_common.h"
#include "ltlo/core/calib.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/settings.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  ltlo::fuzz::quietLogging();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ltlo::fuzz::writeScratchFile("settings", ".yaml", data, size);
  try {
    const ltlo::Settings settings = ltlo::Settings::load(path);
    settings.validate();  // what was loaded must pass the in-memory check too
    (void)settings.describe();
  } catch (const ltlo::ConfigError&) {
  } catch (const ltlo::InputError&) {
  }
  try {
    (void)ltlo::SensorCalib::load(path);  // calib.yaml alone (no algorithm keys)
  } catch (const ltlo::ConfigError&) {
  } catch (const ltlo::InputError&) {
  }
  return 0;
}
