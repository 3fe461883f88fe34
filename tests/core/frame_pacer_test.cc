// FramePacer: frames are due at their stamps' wall times from the first one's (over the rate); a
// frame that starts more than one frame interval after it was due is counted late. An injected
// clock plays the wall time; nothing sleeps.
#include "ltlo/core/frame_pacer.h"

#include <gtest/gtest.h>

namespace ltlo {
namespace {

TEST(FramePacer, FramesAreDueAtTheirStampsOverTheRate) {
  double now = 100.0;
  FramePacer pacer(2.0, [&now] { return now; });
  // The first frame (stamp 5.0) anchors: due at once.
  EXPECT_DOUBLE_EQ(pacer.secondsUntilDue(5.0), 0.0);
  pacer.frameStarts();
  now += 0.01;  // tracked in 10 ms
  // Stamp 5.1 is 0.1 s later in the sequence, 0.05 s at twice its speed: due at 100.05.
  EXPECT_NEAR(pacer.secondsUntilDue(5.1), 0.04, 1e-12);
  now = 100.05;
  pacer.frameStarts();
  now += 0.2;  // this frame took 200 ms: the next (due at 100.10) starts 150 ms late
  EXPECT_DOUBLE_EQ(pacer.secondsUntilDue(5.2), 0.0);
  EXPECT_NEAR(pacer.frameStarts(), 0.15, 1e-12);
  EXPECT_TRUE(pacer.lastFrameLate());
  const FramePacerStats stats = pacer.stats();
  EXPECT_EQ(stats.frames, 3);
  EXPECT_EQ(stats.late_frames, 1);  // 150 ms > its 50 ms interval
  EXPECT_NEAR(stats.max_lag_s, 0.15, 1e-12);
  EXPECT_NEAR(stats.mean_lag_s, 0.05, 1e-12);
  EXPECT_NE(pacer.summary().find("3 frames, 1 (33.3 %)"), std::string::npos) << pacer.summary();
}

TEST(FramePacer, ALagWithinOneFrameIntervalIsNotLateAndTheScheduleDoesNotSlip) {
  double now = 0.0;
  FramePacer pacer(1.0, [&now] { return now; });
  pacer.secondsUntilDue(0.0);
  pacer.frameStarts();
  // Each frame takes 45 ms at 30 Hz (33.3 ms apart): the lag grows by 11.7 ms a frame, late only
  // from the frame whose lag passes one interval; the due times stay on the stamps (no re-anchoring).
  int first_late = -1;
  for (int i = 1; i <= 10; ++i) {
    now += 0.045;
    const double t_s = i / 30.0;
    EXPECT_NEAR(pacer.secondsUntilDue(t_s), 0.0, 1e-12);
    pacer.frameStarts();
    if (first_late < 0 && pacer.stats().late_frames > 0) first_late = i;
  }
  // Lag of frame i: 0.045 i - i / 30 = 7 i / 600 s; above 1/30 s = 20 / 600 s from i = 3.
  EXPECT_EQ(first_late, 3);
  EXPECT_EQ(pacer.stats().late_frames, 8);
  EXPECT_NEAR(pacer.stats().max_lag_s, 70.0 / 600.0, 1e-12);
  // Once tracking is fast again the schedule is caught up: the frame is due when its stamp says.
  now = 20.0 / 30.0 - 0.01;
  EXPECT_NEAR(pacer.secondsUntilDue(20.0 / 30.0), 0.01, 1e-12);
}

TEST(FramePacer, RateZeroIsOffAndCountsNothing) {
  double now = 0.0;
  FramePacer pacer(0.0, [&now] { return now; });
  EXPECT_FALSE(pacer.enabled());
  EXPECT_DOUBLE_EQ(pacer.secondsUntilDue(0.0), 0.0);
  pacer.frameStarts();
  now = 50.0;
  EXPECT_DOUBLE_EQ(pacer.secondsUntilDue(1.0), 0.0);
  pacer.frameStarts();
  EXPECT_EQ(pacer.stats().frames, 0);
  EXPECT_EQ(pacer.summary(), "");
}

}  // namespace
}  // namespace ltlo
