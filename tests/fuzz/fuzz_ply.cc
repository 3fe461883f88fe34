// libFuzzer target: the static map PLY reader (system::readStaticMapPly, the counterpart of the
// static_map.ply writer). Bad files must give InputError.
#include <cstddef>
#include <cstdint>

#include "fuzz_common.h"
#include "ltlo/core/errors.h"
#include "ltlo/system/run_outputs.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  ltlo::fuzz::quietLogging();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ltlo::fuzz::writeScratchFile("ply", ".ply", data, size);
  try {
    (void)ltlo::system::readStaticMapPly(path);
  } catch (const ltlo::InputError&) {
  }
  return 0;
}
