#pragma once
// Synthetic binary descriptors for the bow tests: "images" draw noisy copies of prototypes.
#include <random>
#include <vector>

#include "bow/descriptor.h"

namespace bow::test {

inline Descriptor randomDescriptor(std::mt19937_64& rng) { return {rng(), rng(), rng(), rng()}; }

/// `d` with `flips` random bits inverted.
inline Descriptor flipBits(Descriptor d, int flips, std::mt19937_64& rng) {
  for (int i = 0; i < flips; ++i) {
    const int bit = static_cast<int>(rng() % 256);
    d[bit / 64] ^= std::uint64_t{1} << (bit % 64);
  }
  return d;
}

/// `num_images` images of `per_image` descriptors; image i draws from prototypes of its own
/// subset (so BoW vectors of different images differ) with `flips` bits of noise.
inline std::vector<std::vector<Descriptor>> makeImages(const std::vector<Descriptor>& prototypes, int num_images,
                                                       int per_image, int flips, std::mt19937_64& rng) {
  std::vector<std::vector<Descriptor>> images(num_images);
  for (int i = 0; i < num_images; ++i) {
    for (int j = 0; j < per_image; ++j) {
      const std::size_t p = (static_cast<std::size_t>(i) * 7 + rng() % 40) % prototypes.size();
      images[i].push_back(flipBits(prototypes[p], flips, rng));
    }
  }
  return images;
}

inline std::vector<Descriptor> makePrototypes(int n, std::mt19937_64& rng) {
  std::vector<Descriptor> prototypes;
  for (int i = 0; i < n; ++i) prototypes.push_back(randomDescriptor(rng));
  return prototypes;
}

}  // namespace bow::test
