// Process memory: the resident set follows memory the process touches, and the peak bounds it.
#include "ltlo/core/process_memory.h"

#include <gtest/gtest.h>

#include <cstring>
#include <memory>

namespace ltlo {
namespace {

TEST(ProcessMemory, ResidentSetGrowsWithTouchedMemoryAndThePeakBoundsIt) {
  const double before_mb = currentResidentMb();
  ASSERT_GT(before_mb, 1.0);
  constexpr std::size_t kBytes = 96u << 20;  // 96 MiB, written so every page is resident
  std::unique_ptr<char[]> block(new char[kBytes]);
  std::memset(block.get(), 0x5a, kBytes);
  const double during_mb = currentResidentMb();
  EXPECT_GT(during_mb - before_mb, 80.0);
  EXPECT_GE(peakResidentMb() + 1.0, during_mb);  // ru_maxrss is sampled in KiB: one MB of slack
  volatile char sink = block[kBytes - 1];
  (void)sink;
}

}  // namespace
}  // namespace ltlo
