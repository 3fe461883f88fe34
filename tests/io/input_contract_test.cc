// The input contract of the readers, class by class: benign variants of the formats are read
// like the plain files (CRLF line ends, a UTF-8 byte order mark, comment and blank lines, grey or
// BGRA colour images), and empty inputs are errors naming the file that is empty.
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "common/log_capture.h"
#include "expect_input_error.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/settings.h"
#include "ltlo/io/sequence_reader.h"
#include "test_sequence_writer.h"

namespace ltlo::io {
namespace {

namespace fs = std::filesystem;
using ltlo::test::inputErrorOf;
using test::TempDir;
using test::TestSequenceSpec;

/// The file with CRLF line ends, a comment and a blank line after line 1, and optionally a UTF-8
/// byte order mark in front.
void makeAwkward(const std::string& path, bool with_bom) {
  std::istringstream in(test::readText(path));
  std::string text = with_bom ? "\xEF\xBB\xBF" : "";
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    text += line + "\r\n";
    if (number == 1) text += "# a comment added by the test\r\n\r\n";
  }
  test::writeText(path, text);
}

// `list_lines_added`: lines the awkward index files have above frame 1 that the plain ones lack.
void expectSameReading(const std::string& plain_dir, const std::string& awkward_dir,
                       int list_lines_added) {
  SequenceReader plain = SequenceReader::open(plain_dir);
  SequenceReader awkward = SequenceReader::open(awkward_dir);
  ASSERT_EQ(awkward.frameCount(), plain.frameCount());
  ASSERT_EQ(awkward.imu().size(), plain.imu().size());
  for (size_t i = 0; i < plain.imu().size(); ++i) {
    EXPECT_EQ(awkward.imu()[i].t_s, plain.imu()[i].t_s);
    EXPECT_EQ(awkward.imu()[i].acc_m_s2, plain.imu()[i].acc_m_s2);
    EXPECT_EQ(awkward.imu()[i].gyro_rad_s, plain.imu()[i].gyro_rad_s);
  }
  ASSERT_EQ(awkward.groundTruth().size(), plain.groundTruth().size());
  for (size_t i = 0; i < plain.groundTruth().size(); ++i) {
    EXPECT_EQ(awkward.groundTruth()[i].t_s, plain.groundTruth()[i].t_s);
    EXPECT_EQ(awkward.groundTruth()[i].T_w_x.matrix(), plain.groundTruth()[i].T_w_x.matrix());
  }
  EXPECT_EQ(awkward.calib().camera.camera.fx(), plain.calib().camera.camera.fx());
  EXPECT_EQ(awkward.calib().has_imu, plain.calib().has_imu);
  for (int k = 0; k < plain.frameCount(); ++k) {
    EXPECT_EQ(awkward.frameTime(k), plain.frameTime(k));
    EXPECT_EQ(awkward.frameFiles(k).color_path.substr(awkward_dir.size()),
              plain.frameFiles(k).color_path.substr(plain_dir.size()));
  }
  // Line numbers in messages count the added lines (after line 1, so frame 1 is below them).
  EXPECT_EQ(awkward.frameFiles(1).color_list_line,
            plain.frameFiles(1).color_list_line + list_lines_added);
}

TEST(InputContract, CrlfBomCommentsAndBlankLinesReadLikeThePlainFiles) {
  TempDir tmp("contract_crlf");
  for (const bool with_associations : {true, false}) {
    TestSequenceSpec spec;
    spec.with_associations = with_associations;
    const std::string plain = tmp.file(with_associations ? "plain_a" : "plain_l");
    const std::string awkward = tmp.file(with_associations ? "awkward_a" : "awkward_l");
    test::writeDataFormatSequence(plain, spec);
    test::writeDataFormatSequence(awkward, spec);
    for (const char* name : {"associations.txt", "rgb.txt", "depth.txt", "imu.txt", "groundtruth.txt"}) {
      const std::string path = awkward + "/" + name;
      if (fs::exists(path)) makeAwkward(path, /*with_bom=*/true);
    }
    makeAwkward(awkward + "/calib.yaml", /*with_bom=*/false);  // YAML: CRLF, comment, blank line
    SCOPED_TRACE(with_associations ? "associations.txt" : "rgb.txt + depth.txt");
    expectSameReading(plain, awkward, /*list_lines_added=*/2);
  }
}

// imu.txt as drivers write it: one sensor per row, rows repeated or slightly out of order. The
// test signals are linear in time and each accelerometer row here shares its gyroscope row's
// stamp, so the merged stream must equal the plain file's exactly.
TEST(InputContract, ImuRowsAsDriversWriteThemReadLikeThePlainFile) {
  TempDir tmp("contract_imu_rows");
  TestSequenceSpec spec;
  const std::string plain = tmp.file("plain");
  test::writeDataFormatSequence(plain, spec);
  std::vector<std::string> rows;  // data rows of the plain imu.txt
  {
    std::istringstream in(test::readText(plain + "/imu.txt"));
    for (std::string line; std::getline(in, line);) {
      if (!line.empty() && line[0] != '#') rows.push_back(line);
    }
  }
  ASSERT_GE(rows.size(), 20u);

  const std::string split = tmp.file("split");
  test::writeDataFormatSequence(split, spec);
  std::string split_text = "# timestamp gx gy gz ax ay az\n";
  for (size_t i = 0; i < rows.size(); ++i) {
    std::istringstream fields(rows[i]);
    std::string t, gx, gy, gz, ax, ay, az;
    fields >> t >> gx >> gy >> gz >> ax >> ay >> az;
    const std::string gyro = t + " " + gx + " " + gy + " " + gz + " nan nan nan\n";
    const std::string accel = t + " NaN NaN NaN " + ax + " " + ay + " " + az + "\n";
    split_text += i % 2 == 0 ? gyro + accel : accel + gyro;  // either sensor first
  }
  test::writeText(split + "/imu.txt", split_text);
  expectSameReading(plain, split, /*list_lines_added=*/0);

  const std::string shuffled = tmp.file("shuffled");
  test::writeDataFormatSequence(shuffled, spec);
  std::string shuffled_text;
  for (size_t i = 0; i < rows.size(); ++i) {
    if (i == 4) continue;                                 // sample 4 comes after sample 5
    shuffled_text += rows[i] + "\n";
    if (i == 5) shuffled_text += rows[4] + "\n";
    if (i == 9) shuffled_text += rows[9] + "\n";         // sample 9 twice
  }
  test::writeText(shuffled + "/imu.txt", shuffled_text);
  ltlo::test::LogCapture capture(log::Level::kWarn);
  expectSameReading(plain, shuffled, /*list_lines_added=*/0);
  EXPECT_TRUE(capture.contains(shuffled + "/imu.txt: 1 duplicated stamps dropped (first at line 11), "
                                          "1 samples out of order sorted (first at line 6)"));
}

TEST(InputContract, CrlfSettingsFileLoadsTheSameSettings) {
  TempDir tmp("contract_crlf_settings");
  const std::string source = std::string(LTLO_TEST_SOURCE_DIR) + "/config_yaml/synthetic.yaml";
  const std::string crlf = tmp.file("synthetic_crlf.yaml");
  test::writeText(crlf, test::readText(source));
  makeAwkward(crlf, /*with_bom=*/false);
  const Settings plain = Settings::load(source);
  const Settings awkward = Settings::load(crlf);
  // describe() starts with the file names; everything after them must match.
  const std::string plain_text = plain.describe();
  const std::string awkward_text = awkward.describe();
  EXPECT_EQ(awkward_text.substr(awkward_text.find("Camera.fx")), plain_text.substr(plain_text.find("Camera.fx")));
  EXPECT_TRUE(awkward.unknown_keys.empty());
}

TEST(InputContract, GreyAndBgraColourImagesAreConvertedWithOneWarning) {
  TempDir tmp("contract_grey");
  TestSequenceSpec spec;
  test::writeDataFormatSequence(tmp.file("seq"), spec);
  const std::string color_1 = tmp.file("seq/rgb/" + test::timeText(test::frameTime(spec, 1)) + ".png");
  const std::string color_2 = tmp.file("seq/rgb/" + test::timeText(test::frameTime(spec, 2)) + ".png");
  const std::string color_3 = tmp.file("seq/rgb/" + test::timeText(test::frameTime(spec, 3)) + ".png");
  cv::imwrite(color_1, cv::Mat(spec.height, spec.width, CV_8UC1, cv::Scalar(77)));
  cv::imwrite(color_2, cv::Mat(spec.height, spec.width, CV_8UC1, cv::Scalar(78)));
  cv::imwrite(color_3, cv::Mat(spec.height, spec.width, CV_8UC4, cv::Scalar(1, 2, 3, 200)));
  ltlo::test::LogCapture capture(log::Level::kWarn);
  SequenceReader reader = SequenceReader::open(tmp.file("seq"));
  std::vector<cv::Vec3b> centre;
  while (std::optional<RgbdImuFrame> frame = reader.next()) {
    ASSERT_EQ(frame->color_bgr.type(), CV_8UC3);
    centre.push_back(frame->color_bgr.at<cv::Vec3b>(5, 7));
  }
  ASSERT_EQ(centre.size(), 5u);
  EXPECT_EQ(centre[1], cv::Vec3b(77, 77, 77));
  EXPECT_EQ(centre[2], cv::Vec3b(78, 78, 78));
  EXPECT_EQ(centre[3], cv::Vec3b(1, 2, 3));  // alpha dropped
  const Vec3 original = test::testColor(7, 5, 4);
  EXPECT_EQ(centre[4], cv::Vec3b(original.x(), original.y(), original.z()));
  int warnings = 0;
  for (const std::string& line : capture.lines()) warnings += line.find("converted") != std::string::npos;
  EXPECT_EQ(warnings, 1);
  EXPECT_TRUE(capture.contains(color_1 + ": 8-bit grey colour image converted"));
}

TEST(InputContract, EmptyFrameListsNameTheListFile) {
  TempDir tmp("contract_empty_lists");
  TestSequenceSpec spec;
  const std::string seq = tmp.file("seq");
  test::writeDataFormatSequence(seq, spec);
  test::writeText(seq + "/associations.txt", "# t_rgb rgb t_depth depth\n\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(seq); }),
                       seq + "/associations.txt: lists no RGB-D frames");

  fs::remove(seq + "/associations.txt");
  const std::string depth_list = test::readText(seq + "/depth.txt");
  test::writeText(seq + "/depth.txt", "# no depth\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(seq); }),
                       seq + "/depth.txt: lists no images");
  test::writeText(seq + "/depth.txt", depth_list);
  test::writeText(seq + "/rgb.txt", "");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { SequenceReader::open(seq); }), seq + "/rgb.txt: lists no images");
}

TEST(InputContract, ListsThatNeverPairNameBothLists) {
  TempDir tmp("contract_no_pairs");
  TestSequenceSpec spec;
  spec.with_associations = false;
  spec.depth_offset_s = 0.03;  // beyond the default 0.02 s
  const std::string seq = tmp.file("seq");
  test::writeDataFormatSequence(seq, spec);
  const std::string message = inputErrorOf([&] { SequenceReader::open(seq); });
  LTLO_EXPECT_CONTAINS(message, seq + "/rgb.txt: no RGB-D frames: none of the 5 colour images");
  LTLO_EXPECT_CONTAINS(message, seq + "/depth.txt within 0.020000 s");
}

TEST(InputContract, ImuFileWithoutSamplesIsReportedAndGivesNoImu) {
  TempDir tmp("contract_empty_imu");
  TestSequenceSpec spec;
  const std::string seq = tmp.file("seq");
  test::writeDataFormatSequence(seq, spec);
  test::writeText(seq + "/imu.txt", "# timestamp gx gy gz ax ay az\r\n\r\n");
  ltlo::test::LogCapture capture(log::Level::kWarn);
  const SequenceReader reader = SequenceReader::open(seq);
  EXPECT_FALSE(reader.hasImu());
  EXPECT_EQ(reader.imuPath(), seq + "/imu.txt");
  EXPECT_TRUE(capture.contains(seq + "/imu.txt: no IMU samples"));

  fs::remove(seq + "/imu.txt");
  const SequenceReader without = SequenceReader::open(seq);
  EXPECT_FALSE(without.hasImu());
  EXPECT_TRUE(without.imuPath().empty());
}

}  // namespace
}  // namespace ltlo::io
