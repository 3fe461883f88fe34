// The programs' input contract where it lives in the mains (exit codes and messages), and Ctrl-C:
// bad input exits 2 naming the file and the value (vocabulary, missing IMU), a sequence without
// calib.yaml takes the settings file's calibration with one log line, evaluate normalises
// non-unit quaternions, and SIGINT part-way through rgbd_inertial leaves a complete, parseable
// trajectory of every processed frame; a malformed groundtruth.txt or masks/ (evaluation inputs)
// fails the evaluation (exit 3) after a complete run; reconstruct and check_surfels name a broken
// run file. Runs the built programs on a short generated sequence.
#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "ltlo/io/trajectory_io.h"
#include "program_runner.h"

namespace ltlo::cli_test {
namespace {

namespace fs = std::filesystem;

constexpr int kSequenceFrames = 150;  // 5 s at 30 Hz, 320x240

std::string readFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

void writeFile(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

/// The generated sequence shared by the tests of this binary (ctest runs each test in its own
/// process, possibly two at once): written once into a fresh folder, then renamed into place. The
/// folder name carries the simulate binary's size and time, so a rebuilt simulator writes anew.
const fs::path& sharedSequence() {
  static const fs::path dir = [] {
    const fs::path root = fs::temp_directory_path() / "ltlo_cli_test";
    const fs::path simulate = programPath("simulate");
    const auto stamp = fs::last_write_time(simulate).time_since_epoch().count();
    const fs::path target =
        root / ("static_5s_320x240_" + std::to_string(fs::file_size(simulate)) + "_" + std::to_string(stamp));
    if (fs::exists(target / "groundtruth.txt")) return target;
    fs::create_directories(root);
    const fs::path scratch = root / ("writing_" + std::to_string(::getpid()));
    fs::remove_all(scratch);
    const ProgramResult sim = runProgram({programPath("simulate"), "--scenario", "static", "--seed", "3",
                                          "--seconds", "5", "--width", "320", "--height", "240", "--out",
                                          scratch.string()});
    if (sim.exit_code != 0) throw std::runtime_error("simulate failed: " + sim.describe());
    std::error_code error;
    fs::rename(scratch, target, error);  // fails when another process was first: use theirs
    fs::remove_all(scratch, error);
    for (const fs::directory_entry& entry : fs::directory_iterator(root, error)) {
      const std::string name = entry.path().filename().string();
      if (entry.path() != target && name.rfind("static_5s_", 0) == 0) fs::remove_all(entry.path(), error);
    }
    return target;
  }();
  return dir;
}

/// A copy of the shared sequence's text files (images linked) in `dir`, without `omit`.
fs::path sequenceVariant(const fs::path& dir, const std::vector<std::string>& omit) {
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const fs::directory_entry& entry : fs::directory_iterator(sharedSequence())) {
    const std::string name = entry.path().filename().string();
    if (std::find(omit.begin(), omit.end(), name) != omit.end()) continue;
    if (entry.is_directory()) {
      fs::create_directory_symlink(entry.path(), dir / name);
    } else {
      fs::copy_file(entry.path(), dir / name);
    }
  }
  return dir;
}

class CliContract : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    work_ = fs::temp_directory_path() / ("ltlo_cli_" + test + "_" + std::to_string(::getpid()));
    fs::remove_all(work_);
    fs::create_directories(work_);
  }
  void TearDown() override { fs::remove_all(work_); }

  /// rgbd_inertial (or `program`) with the shipped settings on `sequence`, extra flags appended.
  ProgramResult slam(const fs::path& sequence, const std::vector<std::string>& extra,
                     const std::string& program = "rgbd_inertial", const LineHook& hook = {}) {
    std::vector<std::string> argv = {programPath(program), "--settings", settings_, "--sequence", sequence.string(),
                                     "--out", (work_ / "run").string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return runProgram(argv, "", hook);
  }

  fs::path work_;
  std::string settings_ = sourceDir() + "/config_yaml/synthetic.yaml";
};

// simulate's harder-world options (issue 32) exit 2 on bad values, naming the option and the value.
TEST_F(CliContract, SimulateHarderWorldOptionsExitTwoNamingTheOptionAndValue) {
  const auto simulate = [&](const std::vector<std::string>& extra) {
    std::vector<std::string> argv = {programPath("simulate"), "--scenario", "static", "--seed", "1", "--seconds", "10",
                                     "--width", "80", "--height", "60", "--out", (work_ / "seq").string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return runProgram(argv);
  };
  ProgramResult result;
  result = simulate({"--occluded-start", "sideways"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find("--occluded-start"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("sideways"), std::string::npos) << result.err;
  result = simulate({"--walkers", "0"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find("--walkers"), std::string::npos) << result.err;
  result = simulate({"--walkers", "3"});  // 10 s hold one walker of 5 s after the first 1 s
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find("--walkers 3: each walker needs 5 s"), std::string::npos) << result.err;
  result = simulate({"--walkers", "1", "--three-movers"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find("--three-movers"), std::string::npos) << result.err;
  EXPECT_FALSE(fs::exists(work_ / "seq" / "stats.txt"));
}

TEST_F(CliContract, MissingOrGarbageVocabularyExitsTwoNamingTheFile) {
  const std::string missing = (work_ / "no_such.bin").string();
  ProgramResult result = slam(sharedSequence(), {"--vocabulary", missing});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find(missing + ": vocabulary file does not exist"), std::string::npos) << result.err;

  const fs::path garbage = work_ / "garbage.bin";
  writeFile(garbage, "this is not a vocabulary, just some text\n");
  result = slam(sharedSequence(), {"--vocabulary", garbage.string()});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find(garbage.string() + ": byte 0: not an LTLOBOW1 vocabulary file (magic 'this is ')"),
            std::string::npos)
      << result.err;
}

// The reconstruction tools on a broken run folder: a missing or malformed trajectory, or a
// surfels.ply whose header announces more surfels than the file holds, exits 2 naming the file.
TEST_F(CliContract, ReconstructionToolsExitTwoNamingTheBrokenFile) {
  const fs::path run = work_ / "run_folder";
  fs::create_directories(run);
  const auto reconstruct = [&]() {
    return runProgram({programPath("reconstruct"), "--run", run.string(), "--sequence", sharedSequence().string(),
                       "--out", (work_ / "recon").string(), "--no-snapshots", "--threads", "1"});
  };
  ProgramResult result = reconstruct();
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find((run / "trajectory.txt").string()), std::string::npos) << result.err;

  writeFile(run / "trajectory.txt", "# t tx ty tz qx qy qz qw\n0 0 0 0 0 0 0 1\n0.1 0 0 x 0 0 0 1\n");
  result = reconstruct();
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find((run / "trajectory.txt").string() + ":3"), std::string::npos) << result.err;

  const fs::path ply = work_ / "surfels.ply";
  std::string header = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000000\n";
  for (const char* property : {"float x", "float y", "float z", "float nx", "float ny", "float nz", "uchar red",
                               "uchar green", "uchar blue", "float radius", "float confidence"}) {
    header += std::string("property ") + property + "\n";
  }
  writeFile(ply, header + "end_header\n0123456789");
  result = runProgram({programPath("check_surfels"), "--surfels", ply.string(), "--sequence",
                       sharedSequence().string()});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find(ply.string() + ": truncated: 0 of 4000000000000 surfels"), std::string::npos)
      << result.err;
}

// atlas_info on the atlas files of the fuzz regressions: a valid one is summarised and its static
// points exported; a truncated one exits 2 naming the file, the section and the byte offset.
TEST_F(CliContract, AtlasInfoSummarisesAFileAndNamesTheSectionOfABadOne) {
  const fs::path seeds = fs::path(sourceDir()) / "tests/fuzz/regressions/fuzz_atlas";
  const fs::path ply = work_ / "atlas_static.ply";
  ProgramResult result =
      runProgram({programPath("atlas_info"), (seeds / "valid_two_maps.atlas").string(), "--ply", ply.string()});
  EXPECT_EQ(result.exit_code, 0) << result.describe();
  EXPECT_NE(result.out.find("format_version 1\n"), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("maps 2\n"), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("map 0 keyframes 3 map_points 8 loop_edges 1 t_first_s 0.000000 t_last_s 2.000000\n"),
            std::string::npos)
      << result.out;
  EXPECT_NE(result.out.find("section keyframes offset "), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("ply_points 8\n"), std::string::npos) << result.out;  // 4 of 8 per map at beta 0.9
  EXPECT_TRUE(fs::exists(ply));

  const std::string truncated = (seeds / "truncated_in_keyframes.atlas").string();
  result = runProgram({programPath("atlas_info"), truncated});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find("atlas_info: " + truncated + ": section keyframes at byte "), std::string::npos) << result.err;
  EXPECT_NE(result.err.find(": truncated: "), std::string::npos) << result.err;
}

/// A little-endian u64 of a file's bytes (the atlas file's section table).
std::uint64_t u64At(const std::string& bytes, std::size_t at) {
  std::uint64_t v = 0;
  for (int k = 0; k < 8; ++k) v |= static_cast<std::uint64_t>(static_cast<std::uint8_t>(bytes[at + k])) << (8 * k);
  return v;
}

// rgbd_inertial --resume (issue 31): run 1 saves its atlas with the run state; a damaged or
// truncated run section exits 2 naming the file, the section "run" and the byte; so does a
// --first-frame other than the frame the saved run goes on at. atlas_info reports the run state.
TEST_F(CliContract, AResumeFromABadRunStateExitsTwoNamingTheSection) {
  const std::string atlas = (work_ / "run1.atlas").string();
  ProgramResult result = slam(sharedSequence(), {"--single-thread", "--max-frames", "20", "--save-atlas", atlas});
  ASSERT_EQ(result.exit_code, 0) << result.describe();
  result = runProgram({programPath("atlas_info"), atlas});
  EXPECT_EQ(result.exit_code, 0) << result.describe();
  EXPECT_NE(result.out.find("format_version 2\n"), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("run_next_frame 20\n"), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("section run offset "), std::string::npos) << result.out;

  const std::string bytes = readFile(atlas);
  ASSERT_EQ(static_cast<std::uint8_t>(bytes[12]), 7u);  // seven sections, the run state last
  const std::uint64_t run_offset = u64At(bytes, 16 + 6 * 36 + 16);
  std::string damaged = bytes;
  damaged[run_offset + 100] ^= 0x20;
  const fs::path damaged_path = work_ / "damaged.atlas";
  writeFile(damaged_path, damaged);
  result = slam(sharedSequence(), {"--single-thread", "--load-atlas", damaged_path.string(), "--resume"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find(damaged_path.string() + ": section run at byte " + std::to_string(run_offset) +
                            ": CRC mismatch"),
            std::string::npos)
      << result.err;

  const fs::path truncated_path = work_ / "truncated.atlas";
  writeFile(truncated_path, bytes.substr(0, bytes.size() - 1000));
  result = slam(sharedSequence(), {"--single-thread", "--load-atlas", truncated_path.string(), "--resume"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find(truncated_path.string() + ": section run at byte " + std::to_string(run_offset) +
                            ": truncated"),
            std::string::npos)
      << result.err;

  result = slam(sharedSequence(), {"--single-thread", "--load-atlas", atlas, "--resume", "--first-frame", "7"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find(atlas + ": its run goes on at frame 20, not at --first-frame 7"), std::string::npos)
      << result.err;
  // The run itself resumes (and writes the frames from 20 on).
  result = slam(sharedSequence(), {"--single-thread", "--load-atlas", atlas, "--resume", "--max-frames", "5"});
  EXPECT_EQ(result.exit_code, 0) << result.describe();
  EXPECT_NE(result.out.find("frames 5\n"), std::string::npos) << result.out;
}

TEST_F(CliContract, AMalformedDistortionKeyExitsTwoNamingTheKey) {
  const fs::path lens = sequenceVariant(work_ / "lens", {"calib.yaml"});
  const std::string calib = readFile(sharedSequence() / "calib.yaml");
  {
    std::ofstream out(lens / "calib.yaml");
    out << calib << "Camera.k1: \"-0.1x\"\n";
  }
  ProgramResult result = slam(lens, {"--max-frames", "3"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find((lens / "calib.yaml").string() + ": Camera.k1 = \"-0.1x\", expected a number"),
            std::string::npos)
      << result.err;
  // A lens that folds over inside the image is refused by name too, not run with two pixels per ray.
  {
    std::ofstream out(lens / "calib.yaml");
    out << calib << "Camera.k1: -2.5\n";
  }
  result = slam(lens, {"--max-frames", "3"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find("Camera.k1 = -2.5, expected a lens that can be inverted"), std::string::npos) << result.err;
}

TEST_F(CliContract, RgbdInertialWithoutImuDataIsAnErrorNamingTheAlternatives) {
  const fs::path no_imu = sequenceVariant(work_ / "no_imu", {"imu.txt"});
  ProgramResult result = slam(no_imu, {});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find((no_imu / "imu.txt").string() + ": missing (no IMU data in the sequence); run rgbd "
                                                            "or pass --no-imu for RGB-D only"),
            std::string::npos)
      << result.err;

  writeFile(no_imu / "imu.txt", "# timestamp gx gy gz ax ay az\n");
  result = slam(no_imu, {});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find((no_imu / "imu.txt").string() + ": has no IMU samples"), std::string::npos)
      << result.err;

  // The alternatives named in the message both run.
  result = slam(no_imu, {"--no-imu", "--max-frames", "3"});
  EXPECT_EQ(result.exit_code, 0) << result.describe();
  result = slam(no_imu, {"--max-frames", "3"}, "rgbd");
  EXPECT_EQ(result.exit_code, 0) << result.describe();
}

TEST_F(CliContract, SequenceWithoutCalibYamlUsesTheSettingsCalibrationAndSaysSo) {
  // Settings = synthetic.yaml with its calibration keys replaced by the sequence's calib.yaml.
  std::istringstream config(readFile(settings_));
  std::string merged;
  bool in_matrix = false;
  for (std::string line; std::getline(config, line);) {
    if (in_matrix && !line.empty() && line[0] == ' ') continue;
    in_matrix = false;
    if (line.rfind("Camera.", 0) == 0 || line.rfind("IMU.", 0) == 0 || line.rfind("DepthMapFactor", 0) == 0) {
      in_matrix = line.find("!!opencv-matrix") != std::string::npos;
      continue;
    }
    merged += line + "\n";
  }
  const std::string calib = readFile(sharedSequence() / "calib.yaml");
  merged += calib.substr(calib.find("---\n") + 4);
  settings_ = (work_ / "settings_with_calib.yaml").string();
  writeFile(settings_, merged);

  const fs::path no_calib = sequenceVariant(work_ / "no_calib", {"calib.yaml"});
  const ProgramResult result = slam(no_calib, {"--max-frames", "3"});
  EXPECT_EQ(result.exit_code, 0) << result.describe();
  const std::string expected = (no_calib / "calib.yaml").string() +
                               " not found; calibration (Camera.*, DepthMapFactor, IMU.*) from the settings file " +
                               settings_;
  size_t count = 0;
  for (size_t at = result.err.find(expected); at != std::string::npos; at = result.err.find(expected, at + 1)) {
    ++count;
  }
  EXPECT_EQ(count, 1u) << result.err;
}

TEST_F(CliContract, EvaluateNormalisesNonUnitQuaternionsWithAWarning) {
  // The ground truth with every quaternion scaled by 1.05: the same rotations.
  std::istringstream gt(readFile(sharedSequence() / "groundtruth.txt"));
  std::ostringstream scaled;
  scaled.precision(17);
  for (std::string line; std::getline(gt, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double v[8];
    for (double& value : v) fields >> value;
    scaled << line.substr(0, line.find(' ')) << ' ' << v[1] << ' ' << v[2] << ' ' << v[3];
    for (int i = 4; i < 8; ++i) scaled << ' ' << 1.05 * v[i];
    scaled << "\r\n";  // and CRLF line ends
  }
  const fs::path est = work_ / "scaled.txt";
  writeFile(est, scaled.str());
  const ProgramResult result = runProgram({programPath("evaluate"), "--gt", (sharedSequence() / "groundtruth.txt").string(),
                                           "--est", est.string()});
  ASSERT_EQ(result.exit_code, 0) << result.describe();
  EXPECT_NE(result.err.find(est.string() + ":1: " + std::to_string(kSequenceFrames) + " of " +
                            std::to_string(kSequenceFrames) + " quaternions are not unit (norms 1.05"),
            std::string::npos)
      << result.err;
  std::smatch ate;
  ASSERT_TRUE(std::regex_search(result.out, ate, std::regex("ate_rmse_m ([0-9.e+-]+)"))) << result.out;
  EXPECT_LT(std::stod(ate[1]), 1e-6);  // same poses up to the printed precision
}

// groundtruth.txt and masks/ are evaluation inputs, read only after the run: a malformed one stops
// nothing. The trajectory and the other outputs are written, metrics.json has "evaluation_error"
// instead of the figures that input gives, and the program says which file and line and exits 3.
TEST_F(CliContract, MalformedEvaluationInputsDoNotStopTheRunAndFailTheEvaluationByFileAndLine) {
  constexpr int kFrames = 30;
  const fs::path bad_gt = sequenceVariant(work_ / "bad_gt", {"groundtruth.txt"});
  {
    std::istringstream gt(readFile(sharedSequence() / "groundtruth.txt"));
    std::ostringstream edited;
    int line_number = 0;
    for (std::string line; std::getline(gt, line);) {
      if (++line_number == 4) line = line.substr(0, line.rfind(' ')) + " x";  // qw of the third pose
      edited << line << "\n";
    }
    writeFile(bad_gt / "groundtruth.txt", edited.str());
  }
  const std::string gt_path = (bad_gt / "groundtruth.txt").string();
  ProgramResult result = slam(bad_gt, {"--max-frames", std::to_string(kFrames), "--single-thread"});
  EXPECT_EQ(result.exit_code, 3) << result.describe();
  EXPECT_NE(result.err.find("rgbd_inertial: evaluation failed: " + gt_path + ":4: value 8 is not a number: 'x'"),
            std::string::npos)
      << result.err;
  EXPECT_EQ(result.out.find("ate_rmse_m"), std::string::npos) << result.out;
  const fs::path run = work_ / "run";
  EXPECT_EQ(static_cast<int>(io::readTumTrajectory((run / "trajectory.txt").string()).size()), kFrames);
  EXPECT_TRUE(fs::exists(run / "keyframes.txt"));
  EXPECT_TRUE(fs::exists(run / "static_map.ply"));
  std::string metrics = readFile(run / "metrics.json");
  EXPECT_NE(metrics.find("\"evaluation_error\": \"" + gt_path + ":4: value 8 is not a number: 'x'\""),
            std::string::npos)
      << metrics;
  EXPECT_EQ(metrics.find("ate_rmse_m"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("\"frames\": " + std::to_string(kFrames)), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("\"static_iou\""), std::string::npos) << metrics;  // masks/ still evaluated

  // A masks/ file that is not named by a timestamp (rgbd this time): the same, naming the file; the
  // ATE is there.
  const fs::path bad_masks = sequenceVariant(work_ / "bad_masks", {"masks"});
  fs::create_directory(bad_masks / "masks");
  for (const fs::directory_entry& entry : fs::directory_iterator(sharedSequence() / "masks")) {
    fs::create_symlink(entry.path(), bad_masks / "masks" / entry.path().filename());
  }
  writeFile(bad_masks / "masks" / "not_a_time.png", "x");
  result = slam(bad_masks, {"--max-frames", std::to_string(kFrames)}, "rgbd");
  EXPECT_EQ(result.exit_code, 3) << result.describe();
  const std::string mask_path = (bad_masks / "masks" / "not_a_time.png").string();
  EXPECT_NE(result.err.find("rgbd: evaluation failed: " + mask_path + ": mask file name is not a timestamp"),
            std::string::npos)
      << result.err;
  EXPECT_EQ(static_cast<int>(io::readTumTrajectory((run / "trajectory.txt").string()).size()), kFrames);
  metrics = readFile(run / "metrics.json");
  EXPECT_NE(metrics.find("\"evaluation_error\": \"" + mask_path), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("\"ate_rmse_m\""), std::string::npos) << metrics;
  EXPECT_EQ(metrics.find("\"static_iou\""), std::string::npos) << metrics;
}

// The live viewer on a run: one PNG per rendered picture (Viewer.Fps of sequence time), the counts
// in metrics.json, the HTTP server and the pose stream up and down with the run, every thread
// joined; --pose-stream without a server is a usage error.
TEST_F(CliContract, ViewerWritesItsPicturesAndJoins) {
  constexpr int kFrames = 30;
  const fs::path pictures = work_ / "viewer";
  ProgramResult result = slam(sharedSequence(), {"--max-frames", std::to_string(kFrames), "--viewer-dir", pictures.string(),
                                                 "--viewer-http", "0", "--pose-stream"});
  ASSERT_EQ(result.exit_code, 0) << result.describe();
  int pngs = 0;
  for (const fs::directory_entry& entry : fs::directory_iterator(pictures)) pngs += entry.path().extension() == ".png";
  EXPECT_GT(pngs, 0);
  const std::string metrics = readFile(work_ / "run" / "metrics.json");
  EXPECT_NE(metrics.find("\"viewer_png_frames\": " + std::to_string(pngs)), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("\"viewer_poses\": " + std::to_string(kFrames)), std::string::npos) << metrics;
  EXPECT_NE(result.err.find("viewer: http://127.0.0.1:"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("all threads joined"), std::string::npos) << result.err;

  result = slam(sharedSequence(), {"--max-frames", "3", "--pose-stream"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find("--pose-stream needs --viewer-http"), std::string::npos) << result.err;
}

// view --run: a finished run replayed in the viewer's picture, one picture per 1 / Viewer.Fps of
// sequence time (the default 10 per second: frames 0, 3, 6, ... of the 30 Hz sequence), every
// frame's pose found in the run's trajectory; no outputs is exit 2.
TEST_F(CliContract, ViewReplaysARunIntoPictures) {
  constexpr int kFrames = 30;
  ProgramResult result = slam(sharedSequence(), {"--max-frames", std::to_string(kFrames)});
  ASSERT_EQ(result.exit_code, 0) << result.describe();
  const fs::path pictures = work_ / "replay";
  const fs::path video = work_ / "replay" / "replay.avi";
  result = runProgram({programPath("view"), "--run", (work_ / "run").string(), "--sequence", sharedSequence().string(),
                       "--dir", pictures.string(), "--video", video.string(), "--online"});
  ASSERT_EQ(result.exit_code, 0) << result.describe();
  EXPECT_NE(result.out.find("pictures 10\n"), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("frames_with_pose " + std::to_string(kFrames) + "\n"), std::string::npos) << result.out;
  int pngs = 0;
  for (const fs::directory_entry& entry : fs::directory_iterator(pictures)) pngs += entry.path().extension() == ".png";
  EXPECT_EQ(pngs, 10);
  EXPECT_TRUE(fs::exists(pictures / "000027.png"));
  EXPECT_GT(fs::file_size(video), 1000u);

  result = runProgram({programPath("view"), "--run", (work_ / "run").string(), "--sequence", sharedSequence().string()});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find("give --video FILE and/or --dir DIR"), std::string::npos) << result.err;
  result = runProgram({programPath("view"), "--run", (work_ / "no_run").string(), "--sequence",
                       sharedSequence().string(), "--dir", pictures.string()});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find("no_run/trajectory.txt"), std::string::npos) << result.err;
}

// Ctrl-C part-way: the run stops at a frame boundary, exits 0 and writes a trajectory with one
// parseable line per processed frame. The test sends SIGINT when the progress line of frame 20
// appears (synchronised on the program's output, no sleep).
TEST_F(CliContract, SigintPartWayWritesACompleteParseableTrajectory) {
  bool sent = false;
  const ProgramResult result =
      slam(sharedSequence(), {"--progress-every", "10"}, "rgbd_inertial", [&](const std::string& line, int pid) {
        if (!sent && line.find("frames 20/") != std::string::npos) {
          sent = true;
          kill(pid, SIGINT);
        }
      });
  ASSERT_TRUE(sent) << "no progress line for frame 20: " << result.describe();
  ASSERT_EQ(result.exit_code, 0) << result.describe();
  EXPECT_NE(result.err.find("interrupted after"), std::string::npos) << result.err;

  std::smatch frames;
  ASSERT_TRUE(std::regex_search(result.out, frames, std::regex("(^|\n)frames ([0-9]+)\n"))) << result.out;
  const int processed = std::stoi(frames[2]);
  EXPECT_GE(processed, 20);
  EXPECT_LT(processed, kSequenceFrames);  // stopped part-way
  std::smatch with_pose;
  ASSERT_TRUE(std::regex_search(result.out, with_pose, std::regex("frames_with_pose ([0-9]+)")));
  EXPECT_EQ(std::stoi(with_pose[1]), processed);

  const fs::path trajectory_path = work_ / "run" / "trajectory.txt";
  const io::Trajectory trajectory = io::readTumTrajectory(trajectory_path.string());  // throws if malformed
  ASSERT_EQ(static_cast<int>(trajectory.size()), processed);
  const io::Trajectory gt = io::readTumTrajectory((sharedSequence() / "groundtruth.txt").string());
  for (int k = 0; k < processed; ++k) EXPECT_NEAR(trajectory[k].t_s, gt[k].t_s, 1e-6) << "frame " << k;
  EXPECT_FALSE(fs::exists(trajectory_path.string() + ".part"));
  // The online stream of the same frames is written too, at the same times.
  const io::Trajectory online = io::readTumTrajectory((work_ / "run" / "trajectory_online.txt").string());
  ASSERT_EQ(static_cast<int>(online.size()), processed);
  for (int k = 0; k < processed; ++k) EXPECT_EQ(online[k].t_s, trajectory[k].t_s) << "frame " << k;
  const std::string metrics = readFile(work_ / "run" / "metrics.json");
  EXPECT_NE(metrics.find("\"interrupted\": 1"), std::string::npos);
  EXPECT_NE(metrics.find("\"ate_online_rmse_m\""), std::string::npos) << metrics;
  EXPECT_NE(result.out.find("ate_online_rmse_m "), std::string::npos) << result.out;
  EXPECT_NE(result.err.find("all threads joined"), std::string::npos) << result.err;
}

}  // namespace
}  // namespace ltlo::cli_test
