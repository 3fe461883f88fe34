// A background thread lowers its own priority only: its nice value rises by the increment (capped
// at 19), the thread that started it keeps its own.
#include "ltlo/core/thread_priority.h"

#include <algorithm>
#include <thread>

#include <gtest/gtest.h>

namespace ltlo {
namespace {

TEST(ThreadPriority, LowersOnlyTheCallingThread) {
  const int main_nice = currentThreadNice();
  int before = 0, after = 0, capped = 0, unchanged = 0;
  std::thread worker([&] {
    before = currentThreadNice();
    after = lowerCurrentThreadPriority(3);
    unchanged = lowerCurrentThreadPriority(0);
    capped = lowerCurrentThreadPriority(40);
  });
  worker.join();
  EXPECT_EQ(before, main_nice);  // a new thread starts at its creator's priority
  EXPECT_EQ(after, std::min(19, before + 3));
  EXPECT_EQ(unchanged, after);
  EXPECT_EQ(capped, 19);
  EXPECT_EQ(currentThreadNice(), main_nice);
}

}  // namespace
}  // namespace ltlo
