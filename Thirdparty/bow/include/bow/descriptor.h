#pragma once
/// 256-bit binary descriptors (rotated BRIEF / ORB) as four 64-bit words, and their Hamming distance.
#include <array>
#include <cstdint>

namespace bow {

/// One 256-bit binary descriptor; bit i of the test sequence is bit (i % 64) of word i / 64.
using Descriptor = std::array<std::uint64_t, 4>;

/// Number of differing bits, in [0, 256] (hardware popcount).
inline int hammingDistance(const Descriptor& a, const Descriptor& b) {
  return __builtin_popcountll(a[0] ^ b[0]) + __builtin_popcountll(a[1] ^ b[1]) +
         __builtin_popcountll(a[2] ^ b[2]) + __builtin_popcountll(a[3] ^ b[3]);
}

}  // namespace bow
