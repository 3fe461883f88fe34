// ProgressReporter with a fed clock and a recording writer: FPS, ETA, when lines are written and
// their exact text. No real time is measured.
#include "ltlo/core/progress.h"

#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "common/log_capture.h"

namespace ltlo {
namespace {

struct Recorder {
  double now_s = 100.0;                             // arbitrary epoch: only differences matter
  std::vector<std::pair<std::string, bool>> lines;  // (text, in_place)

  ProgressReporter make(ProgressReporter::Options options) {
    return ProgressReporter(
        std::move(options), [this] { return now_s; },
        [this](const std::string& line, bool in_place) { lines.emplace_back(line, in_place); });
  }
};

TEST(ProgressReporter, ComputesFpsAndEta) {
  Recorder rec;
  ProgressReporter::Options options;
  options.total_frames = 500;
  options.style = ProgressReporter::Style::kSilent;
  ProgressReporter progress = rec.make(options);
  rec.now_s += 5.0;
  progress.frameDone(100);
  const ProgressStatus s = progress.status();
  EXPECT_EQ(s.frames_done, 100);
  EXPECT_DOUBLE_EQ(s.elapsed_s, 5.0);
  EXPECT_DOUBLE_EQ(s.fps, 20.0);
  EXPECT_DOUBLE_EQ(s.eta_s, 20.0);  // 400 frames left at 20 fps
  EXPECT_TRUE(rec.lines.empty());   // silent until finish
  EXPECT_EQ(progress.finish(), "frames: 100 of 500 in 5.0 s (20.0 fps)");
  ASSERT_EQ(rec.lines.size(), 1u);
}

TEST(ProgressReporter, LinesModeWritesEveryNFrames) {
  Recorder rec;
  ProgressReporter::Options options;
  options.total_frames = 250;
  options.style = ProgressReporter::Style::kLines;
  options.log_every_n_frames = 100;
  {
    ProgressReporter progress = rec.make(options);
    for (int i = 0; i < 250; ++i) {
      rec.now_s += 0.05;  // 20 fps
      progress.frameDone();
    }
  }  // destructor writes the summary
  ASSERT_EQ(rec.lines.size(), 3u);
  EXPECT_EQ(rec.lines[0].first, "frames 100/250 (40.0%) | 20.0 fps | elapsed 5.0 s | ETA 7.5 s");
  EXPECT_EQ(rec.lines[1].first, "frames 200/250 (80.0%) | 20.0 fps | elapsed 10.0 s | ETA 2.5 s");
  EXPECT_EQ(rec.lines[2].first, "frames: 250 in 12.5 s (20.0 fps)");
  for (const auto& line : rec.lines) EXPECT_FALSE(line.second);
}

TEST(ProgressReporter, LinesModeCountsCrossedMultiples) {
  Recorder rec;
  ProgressReporter::Options options;
  options.style = ProgressReporter::Style::kLines;
  options.log_every_n_frames = 10;
  ProgressReporter progress = rec.make(options);  // total unknown
  rec.now_s += 1.0;
  progress.frameDone(7);
  progress.frameDone(7);   // 14: crosses 10
  progress.frameDone(3);   // 17: no line
  progress.frameDone(25);  // 42: one line even though 20, 30, 40 were crossed
  ASSERT_EQ(rec.lines.size(), 2u);
  EXPECT_EQ(rec.lines[0].first, "frames 14 | 14.0 fps | elapsed 1.0 s");
  EXPECT_EQ(rec.lines[1].first, "frames 42 | 42.0 fps | elapsed 1.0 s");
  EXPECT_EQ(progress.finish(), "frames: 42 in 1.0 s (42.0 fps)");
  EXPECT_EQ(progress.finish(), "frames: 42 in 1.0 s (42.0 fps)");  // written once
  EXPECT_EQ(rec.lines.size(), 3u);
  progress.frameDone();  // after finish: ignored
  EXPECT_EQ(progress.status().frames_done, 42);
}

TEST(ProgressReporter, TerminalModeRedrawsInPlaceAtRefreshRate) {
  Recorder rec;
  ProgressReporter::Options options;
  options.total_frames = 10;
  options.style = ProgressReporter::Style::kTerminal;
  options.terminal_refresh_s = 0.25;
  ProgressReporter progress = rec.make(options);
  for (int i = 0; i < 10; ++i) {
    rec.now_s += 0.1;
    progress.frameDone();
  }
  // Redraws at t = 0.1 (first), 0.4, 0.7, 1.0 (>= 0.25 s apart), and the last frame always.
  ASSERT_EQ(rec.lines.size(), 4u);
  for (const auto& line : rec.lines) EXPECT_TRUE(line.second);
  EXPECT_EQ(rec.lines[0].first, "frames 1/10 (10.0%) | 10.0 fps | elapsed 0.1 s | ETA 0.9 s");
  EXPECT_EQ(rec.lines[3].first, "frames 10/10 (100.0%) | 10.0 fps | elapsed 1.0 s | ETA 0.0 s");
  progress.finish();
  EXPECT_EQ(rec.lines.back(), std::make_pair(std::string("frames: 10 in 1.0 s (10.0 fps)"), false));
}

TEST(ProgressReporter, InjectedWriterResolvesAutoToLines) {
  Recorder rec;
  ProgressReporter progress = rec.make({});
  EXPECT_EQ(progress.style(), ProgressReporter::Style::kLines);
}

TEST(ProgressReporter, DefaultWriterLogsLinesAndSummary) {
  // Real clock: only the frame counts in the text are asserted, never the times.
  test::LogCapture capture;
  {
    ProgressReporter::Options options;
    options.total_frames = 10;
    options.style = ProgressReporter::Style::kLines;
    options.log_every_n_frames = 5;
    ProgressReporter progress(options);
    for (int i = 0; i < 10; ++i) progress.frameDone();
  }
  const std::vector<std::string> lines = capture.lines();
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0].rfind("[main] info frames 5/10 (50.0%) | ", 0), 0u) << lines[0];
  EXPECT_EQ(lines[1].rfind("[main] info frames 10/10 (100.0%) | ", 0), 0u) << lines[1];
  EXPECT_EQ(lines[2].rfind("[main] info frames: 10 in ", 0), 0u) << lines[2];
}

TEST(ProgressReporter, FormatsDurationsAndUnknownEta) {
  EXPECT_EQ(ProgressReporter::formatDuration(4.24), "4.2 s");
  EXPECT_EQ(ProgressReporter::formatDuration(59.9), "59.9 s");
  EXPECT_EQ(ProgressReporter::formatDuration(187.0), "3m07s");
  EXPECT_EQ(ProgressReporter::formatDuration(7500.0), "2h05m");
  EXPECT_EQ(ProgressReporter::formatDuration(-1.0), "?");
  ProgressStatus s;
  s.frames_done = 0;
  s.total_frames = 100;
  EXPECT_EQ(ProgressReporter::formatStatus("kf", s),
            "kf 0/100 (0.0%) | 0.0 fps | elapsed 0.0 s | ETA ?");
}

}  // namespace
}  // namespace ltlo
