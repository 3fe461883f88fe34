// libFuzzer target: the bag-of-words vocabulary loader (bow::Vocabulary::fromBytes, what load()
// runs on the file's bytes). Bad files must give bow::FileError; a vocabulary that loads must be
// usable: descriptors are transformed (tree descent, TF-IDF) without a crash.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "bow/vocabulary.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const bow::Vocabulary vocabulary =
        bow::Vocabulary::fromBytes(reinterpret_cast<const char*>(data), size, "fuzz.bin");
    const std::vector<bow::Descriptor> descriptors = {
        {0, 0, 0, 0}, {~0ULL, ~0ULL, ~0ULL, ~0ULL}, {0x5555555555555555ULL, 1, 2, 3}, {7, 0, ~0ULL, 9}};
    bow::BowVector bow_vector;
    bow::FeatureVector features;
    for (int depth = 0; depth <= vocabulary.depth() + 1; ++depth) {
      vocabulary.transform(descriptors, &bow_vector, &features, depth);
    }
    for (const bow::Descriptor& d : descriptors) (void)vocabulary.wordWeight(vocabulary.wordOf(d));
  } catch (const bow::FileError&) {
  }
  return 0;
}
