#include "ltlo/io/sequence_reader.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <opencv2/imgcodecs.hpp>

#include "expect_input_error.h"
#include "ltlo/core/errors.h"
#include "test_sequence_writer.h"

namespace ltlo::io {
namespace {

namespace fs = std::filesystem;
using ltlo::test::inputErrorOf;
using test::TempDir;
using test::TestSequenceSpec;

void readAllFrames(const std::string& dir, const SequenceReaderOptions& options = {}) {
  SequenceReader reader = SequenceReader::open(dir, options);
  while (reader.next()) {
  }
}

std::string sequenceDir(const TempDir& tmp) { return tmp.file("seq"); }

SequenceReaderOptions withMasks() {
  SequenceReaderOptions options;
  options.read_masks = true;
  return options;
}

TEST(SequenceReader, ReadsDataFormatFramesValueByValue) {
  TempDir tmp("seq_values");
  TestSequenceSpec spec;
  spec.with_masks = true;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  SequenceReader reader = SequenceReader::open(sequenceDir(tmp), withMasks());
  EXPECT_EQ(reader.layout(), SequenceLayout::kDataFormat);
  ASSERT_EQ(reader.frameCount(), spec.num_frames);
  EXPECT_TRUE(reader.hasImu());
  EXPECT_TRUE(reader.calib().has_imu);
  EXPECT_EQ(reader.calib().camera.camera.width(), spec.width);
  ASSERT_EQ(reader.groundTruth().size(), static_cast<size_t>(spec.num_frames));
  EXPECT_NEAR(reader.groundTruth()[3].T_w_x.translation().x(), 0.3, 1e-12);
  for (int k = 0; k < spec.num_frames; ++k) {
    std::optional<RgbdImuFrame> frame = reader.next();
    ASSERT_TRUE(frame);
    EXPECT_EQ(frame->index, k);
    EXPECT_DOUBLE_EQ(frame->t_s, test::frameTime(spec, k));
    ASSERT_EQ(frame->color_bgr.type(), CV_8UC3);
    ASSERT_EQ(frame->depth_m.type(), CV_32F);
    ASSERT_EQ(frame->mask.type(), CV_8UC1);
    const int u = 7;
    const int v = 5;
    const Vec3 color = test::testColor(u, v, k);
    EXPECT_EQ(frame->color_bgr.at<cv::Vec3b>(v, u), cv::Vec3b(color.x(), color.y(), color.z()));
    EXPECT_FLOAT_EQ(frame->depth_m.at<float>(v, u), test::testDepthRaw(u, v, k) / 1000.0f);
    EXPECT_EQ(frame->mask.at<uint8_t>(0, k), 255);
    EXPECT_EQ(frame->mask.at<uint8_t>(0, k + 1), 0);
  }
  EXPECT_FALSE(reader.next());
  reader.rewind();
  std::optional<RgbdImuFrame> first = reader.next();
  ASSERT_TRUE(first);
  EXPECT_EQ(first->index, 0);
}

TEST(SequenceReader, ImuIntervalsTileTheTimeAxisWithInterpolatedEnds) {
  TempDir tmp("seq_imu");
  TestSequenceSpec spec;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  SequenceReader reader = SequenceReader::open(sequenceDir(tmp));
  double previous_t_s = 0.0;
  size_t interior_samples = 0;
  while (std::optional<RgbdImuFrame> frame = reader.next()) {
    ASSERT_FALSE(frame->imu.empty());
    if (frame->index == 0) {
      ASSERT_EQ(frame->imu.size(), 1u);  // the first frame holds the sample at its own time
    } else {
      EXPECT_EQ(frame->imu.front().t_s, previous_t_s);
      interior_samples += frame->imu.size() - 2;
    }
    EXPECT_EQ(frame->imu.back().t_s, frame->t_s);
    for (size_t i = 0; i < frame->imu.size(); ++i) {
      const ImuSample& s = frame->imu[i];
      if (i > 0) {
        EXPECT_GT(s.t_s, frame->imu[i - 1].t_s);
      }
      // The signals are linear in t, so interpolated boundary samples are exact.
      EXPECT_LT((s.gyro_rad_s - test::testGyro(s.t_s)).norm(), 1e-12);
      EXPECT_LT((s.acc_m_s2 - test::testAcc(s.t_s)).norm(), 1e-12);
    }
    previous_t_s = frame->t_s;
  }
  // 100 Hz between 1.0 s and 1.4 s, none on a frame time: 40 raw samples inside.
  EXPECT_EQ(interior_samples, 40u);
}

TEST(SequenceReader, AssociatesRgbAndDepthListsWithoutAssociationsFile) {
  TempDir tmp("seq_assoc");
  TestSequenceSpec spec;
  spec.with_associations = false;
  spec.depth_offset_s = 0.004;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  SequenceReader reader = SequenceReader::open(sequenceDir(tmp));
  ASSERT_EQ(reader.frameCount(), spec.num_frames);
  std::optional<RgbdImuFrame> frame = reader.next();
  ASSERT_TRUE(frame);
  EXPECT_NEAR(frame->depth_t_s - frame->t_s, 0.004, 1e-9);
  EXPECT_FLOAT_EQ(frame->depth_m.at<float>(0, 0), test::testDepthRaw(0, 0, 0) / 1000.0f);
}

TEST(SequenceReader, DropsColourImagesWithoutDepthWithinTolerance) {
  TempDir tmp("seq_assoc_far");
  TestSequenceSpec spec;
  spec.with_associations = false;
  spec.depth_offset_s = 0.03;  // beyond the default 0.02 s
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp)); }),
                       "no RGB-D frames");
  SequenceReaderOptions options;
  options.max_rgb_depth_dt_s = 0.04;
  EXPECT_EQ(SequenceReader::open(sequenceDir(tmp), options).frameCount(), spec.num_frames);
}

TEST(SequenceReader, MasksFromAnotherFolderOrNone) {
  TempDir tmp("seq_masks_dir");
  TestSequenceSpec spec;
  spec.with_masks = true;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  // A run's segmentation/ folder: frame k's mask is 255 in column k + 2 only.
  const std::string seg_dir = tmp.file("run_segmentation");
  fs::create_directories(seg_dir);
  for (int k = 0; k < spec.num_frames; ++k) {
    cv::Mat mask(spec.height, spec.width, CV_8UC1, cv::Scalar(0));
    mask.col(k + 2).setTo(255);
    cv::imwrite(seg_dir + "/" + test::timeText(test::frameTime(spec, k)) + ".png", mask);
  }
  SequenceReaderOptions options;
  options.masks_dir = seg_dir;
  SequenceReader from_run = SequenceReader::open(sequenceDir(tmp), options);
  for (int k : {3, 1}) {  // load() in any order, next() untouched
    const RgbdImuFrame frame = from_run.load(k);
    EXPECT_EQ(frame.index, k);
    ASSERT_EQ(frame.mask.type(), CV_8UC1);
    EXPECT_EQ(frame.mask.at<uint8_t>(0, k + 2), 255);
    EXPECT_EQ(frame.mask.at<uint8_t>(0, k), 0);
    EXPECT_FLOAT_EQ(frame.depth_m.at<float>(5, 7), test::testDepthRaw(7, 5, k) / 1000.0f);
  }
  EXPECT_EQ(from_run.next()->index, 0);

  options.masks_dir = std::string();  // no masks, although SEQ/masks exists
  SequenceReader without = SequenceReader::open(sequenceDir(tmp), options);
  EXPECT_TRUE(without.frameFiles(0).mask_path.empty());
  EXPECT_TRUE(without.load(2).mask.empty());
  const RgbdImuFrame depth_only = without.load(2, /*with_colour=*/false);
  EXPECT_TRUE(depth_only.color_bgr.empty());
  EXPECT_FLOAT_EQ(depth_only.depth_m.at<float>(5, 7), test::testDepthRaw(7, 5, 2) / 1000.0f);

  options.masks_dir = tmp.file("missing_segmentation");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp), options); }),
                       "missing_segmentation: mask folder does not exist");
}

TEST(SequenceReader, TumRgbdWithoutImuGivesNoSamples) {
  TempDir tmp("seq_tum");
  TestSequenceSpec spec;
  spec.with_imu = false;
  spec.with_associations = false;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  SequenceReader reader = SequenceReader::open(sequenceDir(tmp));
  EXPECT_FALSE(reader.hasImu());
  EXPECT_FALSE(reader.calib().has_imu);
  int count = 0;
  while (std::optional<RgbdImuFrame> frame = reader.next()) {
    EXPECT_TRUE(frame->imu.empty());
    EXPECT_TRUE(frame->mask.empty());
    ++count;
  }
  EXPECT_EQ(count, spec.num_frames);
}

TEST(SequenceReader, ReadsEurocImuCsvInNanoseconds) {
  TempDir tmp("seq_euroc");
  TestSequenceSpec spec;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  test::writeEurocImu(sequenceDir(tmp), spec);
  SequenceReader reader = SequenceReader::open(sequenceDir(tmp));
  ASSERT_TRUE(reader.hasImu());
  EXPECT_NEAR(reader.imu().front().t_s, 0.953, 1e-12);
  reader.next();
  std::optional<RgbdImuFrame> frame = reader.next();
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->imu.size(), 12u);  // 1.003 .. 1.093 plus both ends
  EXPECT_LT((frame->imu.back().acc_m_s2 - test::testAcc(frame->t_s)).norm(), 1e-9);
}

TEST(SequenceReader, ReadsOpenLorisWithAccelAndGyroMerged) {
  TempDir tmp("seq_openloris");
  TestSequenceSpec spec;
  test::writeOpenLorisSequence(sequenceDir(tmp), spec, /*accel_rate_hz=*/250.0,
                               /*gyro_rate_hz=*/200.0);
  EXPECT_EQ(detectLayout(sequenceDir(tmp)), SequenceLayout::kOpenLoris);
  // No calib.yaml: the settings file must provide calibration.
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp)); }), "calib.yaml");
  SequenceReaderOptions options;
  options.calib_override = test::testCalib(spec);
  SequenceReader reader = SequenceReader::open(sequenceDir(tmp), options);
  EXPECT_EQ(reader.layout(), SequenceLayout::kOpenLoris);
  EXPECT_EQ(reader.frameCount(), spec.num_frames);
  EXPECT_EQ(reader.groundTruth().size(), static_cast<size_t>(spec.num_frames));
  // Both streams start at 0.953 s; accel every 4 ms, gyro every 5 ms: over 20 ms the union has
  // 5 + 4 - 1 (shared start) = 8 distinct times.
  const ImuSamples& imu = reader.imu();
  ASSERT_GE(imu.size(), 9u);
  EXPECT_NEAR(imu[8].t_s - imu[0].t_s, 0.020, 1e-9);
  for (const ImuSample& s : imu) {
    EXPECT_LT((s.gyro_rad_s - test::testGyro(s.t_s)).norm(), 1e-12);
    EXPECT_LT((s.acc_m_s2 - test::testAcc(s.t_s)).norm(), 1e-12);
  }
  std::optional<RgbdImuFrame> frame = reader.next();
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->color_bgr.type(), CV_8UC3);
}

// ---- error paths: each message names the file, the line where there is one, and the value ----

TEST(SequenceReaderErrors, MissingFolderAndUnknownLayout) {
  TempDir tmp("seq_err_layout");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(tmp.file("nope")); }),
                       tmp.file("nope") + ": sequence folder does not exist");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(tmp.path()); }),
                       "unknown sequence layout");
}

TEST(SequenceReaderErrors, MissingCalibDepthListAndImage) {
  TempDir tmp("seq_err_missing");
  TestSequenceSpec spec;
  spec.with_calib = false;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp)); }),
                       sequenceDir(tmp) + "/calib.yaml: missing");

  test::testCalib(spec).write(sequenceDir(tmp) + "/calib.yaml");
  fs::remove(sequenceDir(tmp) + "/rgb/" + test::timeText(test::frameTime(spec, 2)) + ".png");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp)); }),
                       "associations.txt:3: image file does not exist: ");

  fs::remove(sequenceDir(tmp) + "/associations.txt");
  fs::remove(sequenceDir(tmp) + "/depth.txt");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp)); }),
                       sequenceDir(tmp) + "/depth.txt: missing");
}

TEST(SequenceReaderErrors, MalformedAndNonIncreasingIndexLines) {
  TempDir tmp("seq_err_index");
  TestSequenceSpec spec;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  const std::string associations = sequenceDir(tmp) + "/associations.txt";
  const std::string original = test::readText(associations);
  test::replaceLine(associations, 2, "1.100000 rgb/1.100000.png");
  std::string message = inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp)); });
  LTLO_EXPECT_CONTAINS(message, associations + ":2:");
  LTLO_EXPECT_CONTAINS(message, "'1.100000 rgb/1.100000.png'");

  test::writeText(associations, original);
  test::replaceLine(associations, 4, "abc rgb/1.300000.png 1.300000 depth/1.300000.png");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp)); }),
                       associations + ":4: colour timestamp is not a number: 'abc'");

  test::writeText(associations, original);
  test::replaceLine(associations, 3, "1.000000 rgb/1.000000.png 1.000000 depth/1.000000.png");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp)); }),
                       associations + ":3: timestamp 1.000000 is not after the previous 1.100000");
}

TEST(SequenceReaderErrors, UnreadableAndWrongTypePngs) {
  TempDir tmp("seq_err_png");
  TestSequenceSpec spec;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  const std::string associations = sequenceDir(tmp) + "/associations.txt";
  const std::string color_2 =
      sequenceDir(tmp) + "/rgb/" + test::timeText(test::frameTime(spec, 2)) + ".png";
  const std::string depth_1 =
      sequenceDir(tmp) + "/depth/" + test::timeText(test::frameTime(spec, 1)) + ".png";

  test::writeText(color_2, "this is not a PNG");
  std::string message = inputErrorOf([&] { readAllFrames(sequenceDir(tmp)); });
  LTLO_EXPECT_CONTAINS(message, associations + ":3: " + color_2 + ": cannot read image");

  cv::imwrite(color_2, cv::Mat(spec.height, spec.width, CV_16UC3, cv::Scalar(7, 7, 7)));  // 16-bit
  message = inputErrorOf([&] { readAllFrames(sequenceDir(tmp)); });
  LTLO_EXPECT_CONTAINS(message, associations + ":3: " + color_2);
  LTLO_EXPECT_CONTAINS(message, "expected 8-bit colour (3-channel, or grey/BGRA converted), found 3 "
                                "channel(s) of 16-bit");

  cv::imwrite(color_2, cv::Mat(spec.height, spec.width, CV_8UC3, cv::Scalar(1, 2, 3)));
  cv::imwrite(depth_1, cv::Mat(spec.height, spec.width, CV_8UC1, cv::Scalar(9)));  // 8-bit depth
  message = inputErrorOf([&] { readAllFrames(sequenceDir(tmp)); });
  LTLO_EXPECT_CONTAINS(message, associations + ":2: " + depth_1);
  LTLO_EXPECT_CONTAINS(message, "expected 16-bit 1-channel depth, found 1 channel(s) of 8-bit");
}

TEST(SequenceReaderErrors, MismatchedImageSizes) {
  TempDir tmp("seq_err_size");
  TestSequenceSpec spec;
  spec.with_masks = true;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  const std::string associations = sequenceDir(tmp) + "/associations.txt";
  const std::string t1 = test::timeText(test::frameTime(spec, 1));
  const std::string color_1 = sequenceDir(tmp) + "/rgb/" + t1 + ".png";
  const std::string depth_1 = sequenceDir(tmp) + "/depth/" + t1 + ".png";
  const std::string mask_1 = sequenceDir(tmp) + "/masks/" + t1 + ".png";

  cv::imwrite(mask_1, cv::Mat(spec.height, spec.width + 1, CV_8UC1, cv::Scalar(0)));
  readAllFrames(sequenceDir(tmp));  // masks are not read unless asked
  LTLO_EXPECT_CONTAINS(
      inputErrorOf([&] { readAllFrames(sequenceDir(tmp), withMasks()); }),
      associations + ":2: " + mask_1 + ": size 17x12 differs from the colour image 16x12");

  cv::imwrite(depth_1, cv::Mat(spec.height - 2, spec.width, CV_16UC1, cv::Scalar(1000)));
  LTLO_EXPECT_CONTAINS(
      inputErrorOf([&] { readAllFrames(sequenceDir(tmp)); }),
      associations + ":2: " + depth_1 + ": size 16x10 differs from the colour image 16x12");

  cv::imwrite(color_1, cv::Mat(spec.height, spec.width * 2, CV_8UC3, cv::Scalar(0, 0, 0)));
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readAllFrames(sequenceDir(tmp)); }),
                       associations + ":2: " + color_1 +
                           ": size 32x12 differs from the calibrated image size 16x12");
}

// imu.txt: line 1 is a comment, sample k is on line k + 2.
class ImuFileErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    test::writeDataFormatSequence(sequenceDir(tmp_), spec_);
    imu_path_ = sequenceDir(tmp_) + "/imu.txt";
  }
  std::string openError(const SequenceReaderOptions& options = {}) {
    return inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp_), options); });
  }
  TempDir tmp_{"seq_err_imu"};
  TestSequenceSpec spec_;
  std::string imu_path_;
};

// Real drivers repeat and reorder stamps: the reader drops repeats, sorts small steps back and
// says so in one warning; only a jump back beyond Sequence.MaxImuReorder stops it.
TEST_F(ImuFileErrors, DuplicatedTimestampIsDroppedWithAWarning) {
  const size_t num_written = SequenceReader::open(sequenceDir(tmp_)).imu().size();
  test::replaceLine(imu_path_, 6, "0.983000 0 0 0 0 0 9.81");  // line 5 is 0.983000 (other values)
  ::testing::internal::CaptureStderr();
  const SequenceReader reader = SequenceReader::open(sequenceDir(tmp_));
  LTLO_EXPECT_CONTAINS(::testing::internal::GetCapturedStderr(),
                       imu_path_ + ": 1 duplicated stamps dropped (1 with values other than the "
                                   "first's; first at line 6), 0 samples out of order sorted");
  const ImuSamples& imu = reader.imu();
  ASSERT_EQ(imu.size(), num_written - 1);
  EXPECT_EQ(imu[3].t_s, 0.983);  // line 5, the first of the stamp, kept
  EXPECT_LT((imu[3].gyro_rad_s - test::testGyro(0.983)).norm(), 1e-12);
  EXPECT_EQ(imu[4].t_s, 1.003);
}

TEST_F(ImuFileErrors, DecreasingTimestampIsSortedOrAJumpBackIsAnError) {
  test::replaceLine(imu_path_, 6, "0.970000 0 0 0 0 0 9.81");  // 0.013 s behind line 5
  ::testing::internal::CaptureStderr();
  const SequenceReader reader = SequenceReader::open(sequenceDir(tmp_));
  LTLO_EXPECT_CONTAINS(::testing::internal::GetCapturedStderr(),
                       imu_path_ + ": 0 duplicated stamps dropped, 1 samples out of order sorted "
                                   "(first at line 6)");
  const ImuSamples& imu = reader.imu();
  ASSERT_GE(imu.size(), 5u);
  EXPECT_EQ(imu[1].t_s, 0.963);
  EXPECT_EQ(imu[2].t_s, 0.970);
  EXPECT_EQ(imu[2].acc_m_s2, Vec3(0, 0, 9.81));
  EXPECT_EQ(imu[3].t_s, 0.973);
  EXPECT_EQ(imu[4].t_s, 0.983);
  EXPECT_EQ(imu[5].t_s, 1.003);

  SequenceReaderOptions strict;
  strict.sequence.max_imu_reorder_s = 0.01;
  LTLO_EXPECT_CONTAINS(openError(strict),
                       imu_path_ + ":6: timestamp 0.970000 goes back by 0.013000 s behind 0.983000 "
                                   "(line 5), more than Sequence.MaxImuReorder = 0.01 s");
}

TEST_F(ImuFileErrors, NanValue) {
  test::replaceLine(imu_path_, 7, "1.003000 0 nan 0 0 0 9.81");
  LTLO_EXPECT_CONTAINS(openError(), imu_path_ + ":7: value 3 is not finite: 'nan'");
}

TEST_F(ImuFileErrors, MalformedLines) {
  test::replaceLine(imu_path_, 8, "1.013000 0 0 0 0 9.81");
  LTLO_EXPECT_CONTAINS(openError(), imu_path_ + ":8: expected 7 values, found 6");
  test::replaceLine(imu_path_, 8, "1.013000 0 0 0 0 x 9.81");
  LTLO_EXPECT_CONTAINS(openError(), imu_path_ + ":8: value 6 is not a number: 'x'");
}

TEST_F(ImuFileErrors, GapFailsOrWarnsByPolicy) {
  // Drop samples 10..19 (lines 12..21): a 0.11 s gap reported at the line after it.
  std::istringstream in(test::readText(imu_path_));
  std::ostringstream out;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (number < 12 || number > 21) out << line << '\n';
  }
  test::writeText(imu_path_, out.str());
  SequenceReaderOptions options;
  options.sequence.max_imu_gap_s = 0.05;
  options.sequence.imu_gap_policy = ImuGapPolicy::kFail;
  LTLO_EXPECT_CONTAINS(openError(options),
                       imu_path_ + ":12: gap of 0.110 s before t = 1.153000 s (limit 0.050 s)");

  options.sequence.imu_gap_policy = ImuGapPolicy::kWarn;
  ::testing::internal::CaptureStderr();
  SequenceReader reader = SequenceReader::open(sequenceDir(tmp_), options);
  const std::string log_text = ::testing::internal::GetCapturedStderr();
  LTLO_EXPECT_CONTAINS(log_text, imu_path_ + ":12: gap of 0.110 s");
  EXPECT_TRUE(reader.hasImu());

  options.sequence.max_imu_gap_s = 0.2;  // the same gap under a looser limit is fine
  options.sequence.imu_gap_policy = ImuGapPolicy::kFail;
  EXPECT_NO_THROW(SequenceReader::open(sequenceDir(tmp_), options));
}

TEST(SequenceReaderErrors, OpenLorisAccelNanAndMissingGyro) {
  TempDir tmp("seq_err_openloris");
  TestSequenceSpec spec;
  test::writeOpenLorisSequence(sequenceDir(tmp), spec, 250.0, 200.0);
  SequenceReaderOptions options;
  options.calib_override = test::testCalib(spec);
  const std::string accel = sequenceDir(tmp) + "/accel.txt";
  test::replaceLine(accel, 3, "0.961000 0.1 -nan 9.8");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp), options); }),
                       accel + ":3: value 3 is not finite: '-nan'");
  fs::remove(sequenceDir(tmp) + "/gyro.txt");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp), options); }),
                       sequenceDir(tmp) + "/gyro.txt: missing");
}

TEST(SequenceReaderErrors, MaskWithWrongType) {
  TempDir tmp("seq_err_mask");
  TestSequenceSpec spec;
  spec.with_masks = true;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  const std::string mask_0 =
      sequenceDir(tmp) + "/masks/" + test::timeText(test::frameTime(spec, 0)) + ".png";
  cv::imwrite(mask_0, cv::Mat(spec.height, spec.width, CV_16UC1, cv::Scalar(0)));
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readAllFrames(sequenceDir(tmp), withMasks()); }),
                       "associations.txt:1: " + mask_0 + ": expected 8-bit 1-channel mask");
}

// The estimator never sees ground truth: by default masks/ is not opened (a mask that is not even
// a PNG goes unnoticed) and frames carry no mask.
TEST(SequenceReader, MasksAreOnlyReadWhenAsked) {
  TempDir tmp("seq_masks_off");
  TestSequenceSpec spec;
  spec.with_masks = true;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  const std::string mask_0 =
      sequenceDir(tmp) + "/masks/" + test::timeText(test::frameTime(spec, 0)) + ".png";
  {
    std::ofstream garbage(mask_0, std::ios::trunc);
    garbage << "not a png";
  }
  SequenceReader reader = SequenceReader::open(sequenceDir(tmp));
  int frames = 0;
  while (std::optional<RgbdImuFrame> frame = reader.next()) {
    EXPECT_TRUE(frame->mask.empty());
    EXPECT_TRUE(frame->mask_path.empty());
    EXPECT_TRUE(reader.frameFiles(frame->index).mask_path.empty());
    ++frames;
  }
  EXPECT_EQ(frames, spec.num_frames);
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readAllFrames(sequenceDir(tmp), withMasks()); }), mask_0);
}

// groundtruth.txt is evaluation only: with read_ground_truth off a malformed file is not opened
// (the SLAM programs read it after the run) but its path is known; by default it is read.
TEST(SequenceReader, GroundTruthIsNotReadWhenTurnedOff) {
  TempDir tmp("seq_gt_off");
  TestSequenceSpec spec;
  test::writeDataFormatSequence(sequenceDir(tmp), spec);
  const std::string gt_path = sequenceDir(tmp) + "/groundtruth.txt";
  {
    std::ofstream broken(gt_path, std::ios::app);
    broken << "9.5 0 0 x 0 0 0 1\n";
  }
  SequenceReaderOptions options;
  options.read_ground_truth = false;
  const SequenceReader reader = SequenceReader::open(sequenceDir(tmp), options);
  EXPECT_TRUE(reader.groundTruth().empty());
  EXPECT_FALSE(reader.hasGroundTruth());
  EXPECT_EQ(reader.groundTruthPath(), gt_path);
  EXPECT_EQ(reader.frameCount(), spec.num_frames);
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(sequenceDir(tmp)); }), gt_path + ":");

  TestSequenceSpec without;
  without.with_groundtruth = false;
  TempDir tmp2("seq_gt_none");
  test::writeDataFormatSequence(sequenceDir(tmp2), without);
  EXPECT_TRUE(SequenceReader::open(sequenceDir(tmp2), options).groundTruthPath().empty());
}

}  // namespace
}  // namespace ltlo::io
