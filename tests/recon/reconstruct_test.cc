// reconstruct() on a short simulated static sequence (with depth noise and holes), posed by its
// ground truth, against the simulator's scene.ply: the accuracy and completeness figures of
// issue 13 on a small scale.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "ltlo/eval/surfel_check.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/recon/reconstruction.h"
#include "ltlo/sim/simulator.h"

namespace ltlo::recon {
namespace {

namespace fs = std::filesystem;

class SimulatedStaticSequence : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(
        (fs::temp_directory_path() / ("recon_sim_" + std::to_string(::getpid()))).string());
    sim::SimOptions options;
    options.width_px = 160;
    options.height_px = 120;
    options.fps = 15.0;
    options.duration_s = 2.0;
    options.scenario = sim::Scenario::kStatic;
    options.seed = 3;
    sim::writeSequence(options, *dir_, /*progress_every=*/0);
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
    dir_ = nullptr;
  }
  static std::string* dir_;
};
std::string* SimulatedStaticSequence::dir_ = nullptr;

TEST_F(SimulatedStaticSequence, SurfelsLieOnTheSceneAndCoverWhatWasSeen) {
  ReconstructionRequest request;
  request.sequence_dir = *dir_;
  request.trajectory_path = *dir_ + "/groundtruth.txt";
  request.progress_every = 0;
  ReconOptions options;
  options.downsample = 1;  // a 160 x 120 input is its own fusion grid
  const ReconstructionResult result = reconstruct(request, options);
  EXPECT_EQ(result.fused_frames.size(), 30u);
  EXPECT_EQ(result.frames_without_pose, 0);
  ASSERT_GT(result.surfels.size(), 5000u);

  eval::SurfelDiscs discs;
  for (const Surfel& s : result.surfels) {
    discs.positions_gt.push_back(s.position_w);
    discs.normals_gt.push_back(s.normal_w);
    discs.radii_m.push_back(s.radius_m);
  }
  const eval::TriangleMesh scene = eval::readPlyMesh(*dir_ + "/scene.ply");
  io::SequenceReaderOptions reader_options;
  reader_options.read_masks = true;
  const io::SequenceReader sequence = io::SequenceReader::open(*dir_, reader_options);
  eval::SurfelCheckOptions check;
  check.frame_step = 3;
  const eval::SurfelCheckResult r = eval::checkSurfels(discs, scene, &sequence, check);
  // Depth noise is 1.5 mm z^2 per pixel (z up to 5.5 m): fused surfels sit within millimetres of
  // the walls; 97 % of the area within 3 cm is issue 13's bar.
  EXPECT_GT(r.static_area_fraction, 0.97);
  EXPECT_LT(r.median_static_distance_m, 0.005);
  EXPECT_EQ(r.dynamic_area_fraction, 0.0);
  // Two seconds give few views per surface, and what entered the view in the last
  // Recon.UnstableTime (1.5 s) is not yet stable, so not written: 0.72 here, where the 45 s
  // sequences reach about 0.9.
  EXPECT_GT(r.seen_samples, 10000);
  EXPECT_GT(r.completeness, 0.65);
}

}  // namespace
}  // namespace ltlo::recon
