// ChangeGate: a change waits for the frame being tracked, a frame waits for a running change, and a
// waiting change goes before the next frame (no starvation of the loop closer by a tracker running
// back to back). Waiting is observed through the gate's own counters, not by sleeping.
#include "ltlo/core/change_gate.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

namespace ltlo {
namespace {

/// Yields until `condition` holds (the other thread has reached its wait).
template <class Condition>
void waitUntil(Condition condition) {
  while (!condition()) std::this_thread::yield();
}

TEST(ChangeGate, AChangeWaitsForTheFrameBeingTracked) {
  ChangeGate gate;
  std::atomic<bool> changed{false};
  gate.beginTracking();
  std::thread closer([&] {
    gate.beginChange();
    changed.store(true);
    gate.endChange();
  });
  waitUntil([&] { return gate.changesWaiting() == 1; });
  EXPECT_FALSE(changed.load());
  gate.endTracking();
  closer.join();
  EXPECT_TRUE(changed.load());
  EXPECT_EQ(gate.changesWaiting(), 0);
}

TEST(ChangeGate, AFrameWaitsForARunningChange) {
  ChangeGate gate;
  std::atomic<bool> tracked{false};
  gate.beginChange();
  std::thread tracker([&] {
    TrackingSection section(gate);
    tracked.store(true);
  });
  waitUntil([&] { return gate.trackingWaiting() == 1; });
  EXPECT_FALSE(tracked.load());
  gate.endChange();
  tracker.join();
  EXPECT_TRUE(tracked.load());
}

// While frame 1 is tracked a change arrives; frame 2 (requested before frame 1 ends) must run
// after the change, not before it.
TEST(ChangeGate, AWaitingChangeGoesBeforeTheNextFrame) {
  ChangeGate gate;
  std::atomic<int> order{0};
  int change_at = -1, frame2_at = -1;
  gate.beginTracking();  // frame 1
  std::thread closer([&] {
    gate.beginChange();
    change_at = order.fetch_add(1);
    gate.endChange();
  });
  waitUntil([&] { return gate.changesWaiting() == 1; });
  std::thread tracker([&] {
    TrackingSection section(gate);  // frame 2
    frame2_at = order.fetch_add(1);
  });
  waitUntil([&] { return gate.trackingWaiting() == 1; });
  gate.endTracking();  // frame 1 ends with both waiting
  closer.join();
  tracker.join();
  EXPECT_EQ(change_at, 0);
  EXPECT_EQ(frame2_at, 1);
}

}  // namespace
}  // namespace ltlo
