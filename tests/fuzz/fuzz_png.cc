// libFuzzer target: the PNG fast path of the sequence reader (src/io/png_decode.h) on arbitrary
// bytes. It must either decode (an image of the announced size) or decline, never crash or read
// out of bounds; whatever it declines goes to cv::imread in the reader.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <opencv2/core/mat.hpp>

#include "fuzz_common.h"
#include "png_decode.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  ltlo::fuzz::quietLogging();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  cv::Mat image;
  if (ltlo::io::decodePngFast(data, size, &image) && (image.empty() || !image.isContinuous())) {
    std::abort();  // a decoded image is never empty and is one block
  }
  return 0;
}
