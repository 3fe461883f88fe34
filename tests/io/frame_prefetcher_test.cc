// FramePrefetcher: the same frames as the plain reader, in order, and a read error delivered after
// the frames before it (so a program stopping on it has processed everything it could).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "ltlo/core/errors.h"
#include "ltlo/io/frame_prefetcher.h"
#include "test_sequence_writer.h"

namespace ltlo::io {
namespace {

TEST(FramePrefetcher, DeliversTheReadersFramesInOrder) {
  test::TempDir dir("prefetch_order");
  test::TestSequenceSpec spec;
  spec.num_frames = 9;
  test::writeDataFormatSequence(dir.path(), spec);
  SequenceReader plain = SequenceReader::open(dir.path());
  SequenceReader ahead = SequenceReader::open(dir.path());
  FramePrefetcher prefetcher(ahead, 2);
  int count = 0;
  while (std::optional<RgbdImuFrame> expected = plain.next()) {
    std::optional<RgbdImuFrame> got = prefetcher.next();
    ASSERT_TRUE(got.has_value()) << "frame " << count;
    EXPECT_EQ(got->t_s, expected->t_s);
    EXPECT_EQ(got->imu.size(), expected->imu.size());
    EXPECT_EQ(cv::norm(got->depth_m, expected->depth_m, cv::NORM_INF), 0.0);
    ++count;
  }
  EXPECT_EQ(count, 9);
  EXPECT_FALSE(prefetcher.next().has_value());
  EXPECT_FALSE(prefetcher.next().has_value());  // stays at the end
}

TEST(FramePrefetcher, StopsAfterMaxFramesAndOnStop) {
  test::TempDir dir("prefetch_stop");
  test::TestSequenceSpec spec;
  spec.num_frames = 8;
  test::writeDataFormatSequence(dir.path(), spec);
  SequenceReader reader = SequenceReader::open(dir.path());
  {
    FramePrefetcher prefetcher(reader, 1, 3);
    int count = 0;
    while (prefetcher.next()) ++count;
    EXPECT_EQ(count, 3);
  }
  SequenceReader other = SequenceReader::open(dir.path());
  FramePrefetcher prefetcher(other, 1);
  ASSERT_TRUE(prefetcher.next().has_value());
  prefetcher.stop();  // the reader thread may be blocked on a full queue: stop must not hang
  EXPECT_FALSE(prefetcher.next().has_value());
}

TEST(FramePrefetcher, ReadErrorComesAfterTheFramesBeforeIt) {
  test::TempDir dir("prefetch_error");
  test::TestSequenceSpec spec;
  spec.num_frames = 6;
  test::writeDataFormatSequence(dir.path(), spec);
  // Corrupt the colour image of frame 4.
  SequenceReader probe = SequenceReader::open(dir.path());
  const std::string rgb = probe.frameFiles(4).color_path;
  std::ofstream(rgb, std::ios::trunc) << "not a png";
  SequenceReader reader = SequenceReader::open(dir.path());
  FramePrefetcher prefetcher(reader, 3);
  for (int k = 0; k < 4; ++k) ASSERT_TRUE(prefetcher.next().has_value()) << "frame " << k;
  try {
    prefetcher.next();
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(std::filesystem::path(rgb).filename().string()), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(prefetcher.next().has_value());
}

}  // namespace
}  // namespace ltlo::io
