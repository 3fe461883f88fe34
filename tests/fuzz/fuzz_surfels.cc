// libFuzzer target: the surfels.ply reader (recon::readSurfelPly, read by reconstruct --surfels and
// check_surfels). Bad files must give InputError.
#include <cstddef>
#include <cstdint>

#include "fuzz_common.h"
#include "ltlo/core/errors.h"
#include "ltlo/recon/surfel_ply.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  ltlo::fuzz::quietLogging();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ltlo::fuzz::writeScratchFile("surfels", ".ply", data, size);
  try {
    (void)ltlo::recon::readSurfelPly(path);
  } catch (const ltlo::InputError&) {
  }
  return 0;
}
