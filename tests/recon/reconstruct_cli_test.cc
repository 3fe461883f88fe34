// Runs the built reconstruct program (path from CMake: LTLO_RECONSTRUCT_BINARY) on a tiny
// generated sequence: it fuses and writes its outputs, and exits 2 naming the file on a run folder
// with a missing or malformed trajectory.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <sstream>

#include "ltlo/io/trajectory_io.h"
#include "test_sequence_writer.h"

namespace ltlo {
namespace {

namespace fs = std::filesystem;
using io::test::readText;
using io::test::TempDir;
using io::test::writeText;

struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

RunResult runReconstruct(const TempDir& tmp, const std::string& args) {
  const std::string command = std::string(LTLO_RECONSTRUCT_BINARY) + " " + args + " > " +
                              tmp.file("stdout.txt") + " 2> " + tmp.file("stderr.txt");
  const int status = std::system(command.c_str());
  RunResult result;
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.out = readText(tmp.file("stdout.txt"));
  result.err = readText(tmp.file("stderr.txt"));
  return result;
}

// A 5-frame 16 x 12 sequence and a run folder holding its ground truth as the trajectory.
class ReconstructCli : public ::testing::Test {
 protected:
  ReconstructCli() : tmp_("recon_cli") {
    io::test::TestSequenceSpec spec;
    io::test::writeDataFormatSequence(tmp_.file("seq"), spec);
    fs::create_directories(tmp_.file("run"));
    fs::copy_file(tmp_.file("seq/groundtruth.txt"), tmp_.file("run/trajectory.txt"));
  }
  std::string args(const std::string& extra = "") const {
    return "--run " + tmp_.file("run") + " --sequence " + tmp_.file("seq") + " --out " +
           tmp_.file("out") + " " + extra;
  }
  TempDir tmp_;
};

TEST_F(ReconstructCli, FusesAndWritesSurfelsAndSnapshots) {
  const RunResult run = runReconstruct(tmp_, args("--size 96x72"));
  ASSERT_EQ(run.exit_code, 0) << run.err;
  std::map<std::string, std::string> values;
  std::istringstream lines(run.out);
  std::string name, value;
  while (lines >> name >> value) values[name] = value;
  EXPECT_EQ(values["frames_fused"], "5");
  EXPECT_EQ(values["all_pixels"], "1");  // the run has no segmentation/
  EXPECT_TRUE(fs::is_regular_file(tmp_.file("out/surfels.ply")));
  EXPECT_TRUE(fs::is_regular_file(tmp_.file("out/reconstruct.json")));
  for (const char* picture : {"bird_eye", "path_1", "orbit_7", "frames", "contact_sheet"}) {
    EXPECT_TRUE(fs::is_regular_file(tmp_.file("out/snapshots/") + picture + ".png")) << picture;
  }
}

TEST_F(ReconstructCli, MissingTrajectoryExitsTwoNamingTheFile) {
  fs::remove(tmp_.file("run/trajectory.txt"));
  const RunResult run = runReconstruct(tmp_, args());
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find(tmp_.file("run/trajectory.txt") + ": trajectory file does not exist"),
            std::string::npos)
      << run.err;
  EXPECT_FALSE(fs::exists(tmp_.file("out/surfels.ply")));
}

TEST_F(ReconstructCli, MalformedTrajectoryExitsTwoNamingFileAndLine) {
  io::test::replaceLine(tmp_.file("run/trajectory.txt"), 3, "1.100000 0.1 0.2 zero 0 0 0 1");
  RunResult run = runReconstruct(tmp_, args());
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find(tmp_.file("run/trajectory.txt") + ":3:"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("zero"), std::string::npos) << run.err;

  // Well-formed, but no pose near any frame (times shifted by an hour).
  io::Trajectory shifted = io::readTumTrajectory(tmp_.file("seq/groundtruth.txt"));
  for (io::StampedPose& pose : shifted) pose.t_s += 3600.0;
  io::writeTumTrajectory(tmp_.file("run/trajectory.txt"), shifted);
  run = runReconstruct(tmp_, args());
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find(tmp_.file("run/trajectory.txt") + ": no pose within"), std::string::npos)
      << run.err;

  writeText(tmp_.file("run/trajectory.txt"), "# timestamp tx ty tz qx qy qz qw\n");
  run = runReconstruct(tmp_, args());
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find(tmp_.file("run/trajectory.txt") + ": trajectory has no poses"),
            std::string::npos)
      << run.err;
}

TEST_F(ReconstructCli, OtherBadInputExitsTwo) {
  RunResult run = runReconstruct(tmp_, "--run " + tmp_.file("no_run") + " --sequence " +
                                           tmp_.file("seq") + " --out " + tmp_.file("out"));
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find(tmp_.file("no_run") + ": run folder does not exist"), std::string::npos)
      << run.err;
  run = runReconstruct(tmp_, args("--trajectory " + tmp_.file("nothing.txt")));
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find(tmp_.file("nothing.txt") + ": trajectory file does not exist"),
            std::string::npos)
      << run.err;
  fs::create_directories(tmp_.file("run/segmentation"));  // exists but holds no masks
  run = runReconstruct(tmp_, args());
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("that have a segmentation mask"), std::string::npos) << run.err;
  run = runReconstruct(tmp_, args("--size 10x10"));
  EXPECT_EQ(run.exit_code, 2);
}

}  // namespace
}  // namespace ltlo
