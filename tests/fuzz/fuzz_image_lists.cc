// libFuzzer target: the frame index files, each input read as rgb.txt/depth.txt ("timestamp
// path") and as associations.txt ("t_rgb rgb t_depth depth"), then associated with itself the
// way rgb.txt and depth.txt are paired. Bad lines must give InputError.
#include <cstddef>
#include <cstdint>
#include <sstream>

#include "fuzz_common.h"
#include "ltlo/core/errors.h"
#include "ltlo/io/associate.h"
#include "parsers.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  ltlo::fuzz::quietLogging();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = ltlo::fuzz::asText(data, size);
  try {
    std::istringstream in(text);
    const std::vector<ltlo::io::detail::ListedImage> images =
        ltlo::io::detail::parseImageList(in, "SEQ", "SEQ/rgb.txt");
    std::vector<double> times_s;
    for (const auto& image : images) times_s.push_back(image.t_s);
    std::vector<double> shifted_s = times_s;
    for (double& t_s : shifted_s) t_s += 0.004;
    (void)ltlo::io::associateTimestamps(times_s, shifted_s, 0.02);
  } catch (const ltlo::InputError&) {
  }
  try {
    std::istringstream in(text);
    (void)ltlo::io::detail::parseAssociations(in, "SEQ", "SEQ/associations.txt");
  } catch (const ltlo::InputError&) {
  }
  return 0;
}
