// End to end: a run resumed from the atlas file it saved continues as the run that went on in
// memory (issue 31). System, synchronous (deterministic), on a short generated ltlo sequence
// (320x240 at 15 Hz, boxes crossing the view):
//   - the continuous run tracks frames [0, end);
//   - run 1 tracks [0, N), shuts down and saves its atlas with the run state;
//   - the file loaded with SystemOptions::resume and saved again straight away is the same file,
//     byte for byte: every field of the maps and of each stage's run state comes back;
//   - run 2 resumes at frame N (the segmenter's previous frame rebuilt from frame N - 1's images)
//     and tracks [N, end): its online and final poses of those frames are the continuous run's
//     (the acceptance is 0.1 mm; they are bit-identical), so are its keyframes and map points.
// Split before the IMU initialisation (2 s) and after it (6 s, where the segmenter also keeps earlier
// frames as references, rebuilt from their images); on a blind start, between the IMU
// initialisation from the rest before the map and the map's own.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "end_to_end_suite.h"
#include "ltlo/core/log.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/sim/simulator.h"
#include "ltlo/system/system.h"

namespace ltlo::system {
namespace {

namespace fs = std::filesystem;
using test_support::EndToEndSuite;
using test_support::shortRunSettings;
using test_support::shortRunSimOptions;

constexpr double kSequenceSeconds = 9.0;

struct ResumeRun {
  RunReport report;
  int frames = 0;
  /// Local mapping's IMU state when the run stopped: initialised from the rest before the map, its
  /// own initialisation still to come (ImuInit.FromPreMapRest).
  bool awaiting_own_imu_initialisation = false;
  /// Frames the segmenter kept as references (Dense.ReferenceBaseline) at the resume.
  int kept_frames = 0;
};

std::string readBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// Largest position difference (m) of `resumed`'s frames from `continuous`'s same frames (by time),
/// and how many of them are bit-identical; every resumed frame must have its continuous twin.
struct PoseDifference {
  double max_m = 0.0;
  int identical = 0;
  int compared = 0;
};
PoseDifference compare(const std::vector<FramePose>& continuous, const std::vector<FramePose>& resumed) {
  PoseDifference difference;
  for (const FramePose& pose : resumed) {
    const auto twin = std::find_if(continuous.begin(), continuous.end(),
                                   [&](const FramePose& other) { return other.t_s == pose.t_s; });
    if (twin == continuous.end()) {
      ADD_FAILURE() << "frame at t = " << pose.t_s << " s is not in the continuous run";
      continue;
    }
    ++difference.compared;
    difference.max_m = std::max(difference.max_m, (twin->T_w_c.translation() - pose.T_w_c.translation()).norm());
    if (twin->T_w_c.translation() == pose.T_w_c.translation() &&
        twin->T_w_c.quaternion().coeffs() == pose.T_w_c.quaternion().coeffs()) {
      ++difference.identical;
    }
  }
  return difference;
}

class ResumeEndToEnd : public EndToEndSuite {
 public:
  static void SetUpTestSuite() {
    createSuiteResources("ltlo_resume_");
    sequence_ = (root() / "ltlo_s2").string();
    sim::writeSequence(shortRunSimOptions(sim::Scenario::kLtlo, 2, kSequenceSeconds), sequence_, 0);
    continuous_ = std::make_unique<ResumeRun>(run(0, -1, "", false));
  }
  static void TearDownTestSuite() {
    continuous_.reset();
    removeSuiteResources();
  }

  static io::SequenceReader reader() {
    io::SequenceReaderOptions options;
    options.calib_override = shortRunSettings(sequence_).calib;
    options.imu_margin_s = 0.06;  // as rgbd_inertial with the time-offset estimate
    return io::SequenceReader::open(sequence_, options);
  }

  /// Frames [first, last) (last < 0: to the end), in a new System loading `atlas` to resume when
  /// given; saves the atlas to `save` when given.
  static ResumeRun run(int first, int last, const std::string& atlas, bool resume, const std::string& save = "") {
    io::SequenceReader frames = reader();
    SystemOptions options;
    options.threaded = false;
    options.load_atlas_path = atlas;
    options.resume = resume;
    ResumeRun result;
    System system(shortRunSettings(sequence_), vocabulary(), options);
    if (resume) {
      const std::optional<ResumePoint> point = system.resumePoint();
      EXPECT_TRUE(point.has_value());
      if (!point) return result;
      EXPECT_EQ(point->next_frame_index, static_cast<std::uint64_t>(first));
      EXPECT_EQ(point->last_frame_t_s, frames.frameTime(first - 1));
      EXPECT_FALSE(point->settings_differ);
      for (const double t_s : point->kept_frame_t_s) {  // oldest first, before the previous frame
        int index = first - 2;
        while (index >= 0 && frames.frameTime(index) > t_s) --index;
        EXPECT_GE(index, 0) << "no frame at the kept time " << t_s;
        if (index < 0) return result;
        io::RgbdImuFrame kept = frames.load(index);
        blank(kept);
        system.restoreKeptFrame(kept);
      }
      result.kept_frames = static_cast<int>(point->kept_frame_t_s.size());
      if (point->previous_frame_t_s) {
        io::RgbdImuFrame previous = frames.load(first - 1);
        blank(previous);
        system.restorePreviousFrame(previous);
      }
    }
    frames.seek(first);
    while (last < 0 || first + result.frames < last) {
      std::optional<io::RgbdImuFrame> input = frames.next();
      if (!input) break;
      blank(*input);
      system.trackFrame(*input);
      ++result.frames;
    }
    result.awaiting_own_imu_initialisation = system.imuState().awaiting_own_initialisation;
    system.shutdown();
    if (!save.empty()) system.saveAtlas(save);
    result.report = system.report(1.0);
    return result;
  }

  /// Run 1 to `split`, then run 2 from there; checks the file's round trip on the way.
  static ResumeRun resumeAt(int split) {
    const std::string atlas = (root() / ("run1_" + std::to_string(split) + ".atlas")).string();
    const ResumeRun first = run(0, split, "", false, atlas);
    EXPECT_EQ(first.frames, split);
    // Loaded to resume and saved again before any frame: the same bytes.
    const std::string again = atlas + ".again";
    run(split, split, atlas, true, again);
    EXPECT_EQ(readBytes(again), readBytes(atlas)) << "split " << split;
    return run(split, -1, atlas, true);
  }

  static void expectContinuation(const ResumeRun& resumed, int split) {
    const ResumeRun& continuous = *continuous_;
    ASSERT_EQ(static_cast<int>(resumed.report.trajectory.size()), continuous_->frames - split);
    const PoseDifference online = compare(continuous.report.trajectory_online, resumed.report.trajectory_online);
    const PoseDifference final = compare(continuous.report.trajectory, resumed.report.trajectory);
    log::info("resume at frame ", split, ": online max ", online.max_m * 1e3, " mm (", online.identical, "/",
              online.compared, " identical), final max ", final.max_m * 1e3, " mm (", final.identical, "/",
              final.compared, " identical)");
    EXPECT_LT(online.max_m, 1e-4);
    EXPECT_LT(final.max_m, 1e-4);
    EXPECT_EQ(online.identical, online.compared);
    EXPECT_EQ(final.identical, final.compared);
    // The maps the two runs end with.
    EXPECT_EQ(resumed.report.counts.keyframes, continuous.report.counts.keyframes);
    EXPECT_EQ(resumed.report.counts.map_points, continuous.report.counts.map_points);
    EXPECT_EQ(resumed.report.counts.maps, continuous.report.counts.maps);
    ASSERT_EQ(resumed.report.keyframes.size(), continuous.report.keyframes.size());
    for (std::size_t k = 0; k < resumed.report.keyframes.size(); ++k) {
      EXPECT_EQ(resumed.report.keyframes[k].id, continuous.report.keyframes[k].id);
      EXPECT_EQ(resumed.report.keyframes[k].T_w_c.translation(), continuous.report.keyframes[k].T_w_c.translation());
    }
  }

  /// Frames before this time get a uniform grey image (a view too poor for a map; < 0: none).
  static void blank(io::RgbdImuFrame& input) {
    if (input.t_s < blank_until_s_) input.color_bgr.setTo(cv::Scalar(128, 128, 128));
  }

  static inline std::string sequence_;
  static inline std::unique_ptr<ResumeRun> continuous_;
  static inline double blank_until_s_ = -1.0;
};

/// The blind start of StandstillEndToEnd (static room, still for 1.5 s, no image until 2.5 s): the
/// first map starts at 2.5 s and local mapping initialises the IMU from the rest before it at
/// about 3.2 s, then keeps tracking's early keyframes until its own initialisation (>= 4.5 s).
class ResumeAfterPreMapRest : public ResumeEndToEnd {
 public:
  static void SetUpTestSuite() {
    createSuiteResources("ltlo_resume_rest_");
    sequence_ = (root() / "blind_start").string();
    sim::SimOptions options = shortRunSimOptions(sim::Scenario::kStatic, 1, 6.0);
    options.stills = {{0.0, 1.5}};
    sim::writeSequence(options, sequence_, 0);
    blank_until_s_ = 2.5;
    continuous_ = std::make_unique<ResumeRun>(run(0, -1, "", false));
  }
  static void TearDownTestSuite() {
    continuous_.reset();
    blank_until_s_ = -1.0;
    removeSuiteResources();
  }
};

TEST_F(ResumeEndToEnd, ResumedBeforeTheImuInitialisationContinuesExactly) {
  ASSERT_FALSE(continuous_->report.trajectory.empty());
  const ResumeRun resumed = resumeAt(30);
  expectContinuation(resumed, 30);
  EXPECT_TRUE(resumed.report.counts.imu_initialised);  // it initialised after the resume, as the continuous run
}

TEST_F(ResumeEndToEnd, ResumedAfterTheImuInitialisationContinuesExactly) {
  const ResumeRun resumed = resumeAt(90);
  expectContinuation(resumed, 90);
  // The segmenter's reference frames (Dense.ReferenceBaseline 0.3 s, one kept every 0.15 s: at
  // 15 Hz every third frame, up to 4; 2 here) came back from their images with the previous frame.
  EXPECT_GE(resumed.kept_frames, 1);
  // This run's own frames are what it reports; the saved run's records are context only.
  EXPECT_EQ(resumed.report.counts.frames, continuous_->frames - 90);
  EXPECT_EQ(resumed.report.counts.frames_with_pose, continuous_->frames - 90);
}

TEST_F(ResumeAfterPreMapRest, ResumedBetweenTheInitialisationFromTheRestAndTheMapsOwnContinuesExactly) {
  // Split at 3.8 s: the IMU initialised from the rest before the map, the map's own initialisation
  // (and the end of the early keyframes) still to come; both flags travel in the run state.
  constexpr int kSplit = 57;
  const ResumeRun first = run(0, kSplit, "", false);
  ASSERT_TRUE(first.report.counts.imu_initialised);
  ASSERT_TRUE(first.awaiting_own_imu_initialisation);
  const ResumeRun resumed = resumeAt(kSplit);
  expectContinuation(resumed, kSplit);
  EXPECT_FALSE(resumed.awaiting_own_imu_initialisation);  // the map's own followed, as in one piece
}

}  // namespace
}  // namespace ltlo::system
