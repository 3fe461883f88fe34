// The live viewer (issue 30): the picture of a known state has the expected pixel classes, the
// viewer thread paces, renders, writes and drops as documented, and leaves no thread behind.
#include <gtest/gtest.h>

#include <unistd.h>

#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "ltlo/core/errors.h"
#include "ltlo/core/thread_names.h"
#include "ltlo/viewer/run_replay.h"
#include "ltlo/viewer/viewer.h"
#include "ltlo/viewer/viewer_renderer.h"

namespace ltlo::viewer {
namespace {

namespace fs = std::filesystem;

/// A camera at the origin looking along +z; a wall of static points 4 m ahead, dynamic points at
/// 3 m, three keyframes behind the camera with a loop edge between the first and the last.
ViewerState knownState() {
  ViewerState state;
  state.frame.index = 7;
  state.frame.t_s = 0.7;
  state.frame.color_bgr = cv::Mat(240, 320, CV_8UC3, cv::Scalar(200, 200, 200));
  state.frame.dynamic_mask = cv::Mat(60, 80, CV_8U, cv::Scalar(0));
  state.frame.dynamic_mask(cv::Rect(0, 0, 40, 60)) = 255;  // left half dynamic
  state.frame.keypoints = {{240.0f, 120.0f, KeypointClass::kTracked}, {280.0f, 60.0f, KeypointClass::kUntracked},
                           {60.0f, 120.0f, KeypointClass::kDynamic}};
  state.frame.has_pose = true;
  state.frame.tracked = true;
  state.frame.state = "ok";
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 5; ++j) {
      state.map.points_w.emplace_back(-1.0f + 0.2f * i, -0.5f + 0.2f * j, 4.0f);
      state.map.beta.push_back(0.9f);
    }
  }
  for (int i = 0; i < 20; ++i) {
    state.map.points_w.emplace_back(-0.95f + 0.1f * i, 0.6f, 3.0f);
    state.map.beta.push_back(0.1f);
  }
  for (int k = 0; k < 3; ++k) state.map.keyframes_T_w_c.push_back(SE3(Quat::Identity(), Vec3(0.4 * (k - 1), 0.0, -0.8)));
  state.map.covisibility = {{0, 1}, {1, 2}};
  state.map.loop_edges = {{0, 2}};
  state.map.trajectory_w = {Eigen::Vector3f(-0.4f, 0.0f, -0.8f), Eigen::Vector3f(0.0f, 0.0f, -0.4f),
                            Eigen::Vector3f(0.0f, 0.0f, 0.0f)};
  state.map.keyframes_all_maps = 3;
  state.map.maps = 1;
  state.map.loops = 1;
  return state;
}

int countLabel(const cv::Mat& labels, ViewerLabel label) { return cv::countNonZero(labels == label); }

TEST(ViewerRenderer, KnownStateHasTheExpectedPixelClasses) {
  ViewerOptions options;
  options.panel_width = 320;
  options.panel_height = 240;
  options.point_size_px = 2;
  ViewerRenderer renderer(options);
  const ViewerPicture picture = renderer.render(knownState());
  ASSERT_EQ(picture.bgr.size(), cv::Size(640, 240));
  ASSERT_EQ(picture.labels_3d.size(), cv::Size(320, 240));

  // 50 static and 20 dynamic points of 2x2 px, apart from each other: every one visible.
  EXPECT_EQ(countLabel(picture.labels_3d, kLabelStaticPoint), 50 * 4);
  EXPECT_EQ(countLabel(picture.labels_3d, kLabelDynamicPoint), 20 * 4);
  EXPECT_GT(countLabel(picture.labels_3d, kLabelKeyFrame), 30);      // three frusta
  EXPECT_GT(countLabel(picture.labels_3d, kLabelCurrentCamera), 30);  // the current camera's frustum
  EXPECT_GT(countLabel(picture.labels_3d, kLabelLoopEdge), 10);
  EXPECT_GT(countLabel(picture.labels_3d, kLabelTrajectory), 5);
  // Static points green, dynamic ones red (colour by beta).
  const cv::Mat right = picture.bgr(cv::Rect(320, 0, 320, 240));
  int green = 0, red = 0;
  for (int v = 0; v < 240; ++v) {
    for (int u = 0; u < 320; ++u) {
      const cv::Vec3b p = right.at<cv::Vec3b>(v, u);
      const std::uint8_t label = picture.labels_3d.at<std::uint8_t>(v, u);
      if (label == kLabelStaticPoint && p[1] > 150 && p[2] < 120) ++green;
      if (label == kLabelDynamicPoint && p[2] > 150 && p[1] < 120) ++red;
    }
  }
  EXPECT_EQ(green, 50 * 4);
  EXPECT_EQ(red, 20 * 4);

  // Left panel: the dynamic half tinted red, the static half grey; keypoints in their colours.
  const cv::Mat left = picture.bgr(cv::Rect(0, 0, 320, 240));
  const cv::Vec3b tinted = left.at<cv::Vec3b>(200, 40);
  const cv::Vec3b plain = left.at<cv::Vec3b>(200, 280);
  EXPECT_EQ(tinted, cv::Vec3b(100, 100, 228));
  EXPECT_EQ(plain, cv::Vec3b(200, 200, 200));
  EXPECT_EQ(left.at<cv::Vec3b>(120, 240), cv::Vec3b(0, 255, 0));    // tracked
  EXPECT_EQ(left.at<cv::Vec3b>(60, 280), cv::Vec3b(255, 160, 0));   // untracked
  EXPECT_EQ(left.at<cv::Vec3b>(120, 60), cv::Vec3b(0, 0, 255));     // dynamic

  // A loop that just landed: the loop edge is drawn thicker (from the same following camera).
  ViewerOptions following = options;
  following.loop_overview = false;
  ViewerRenderer following_renderer(following);
  ViewerState flashing = knownState();
  flashing.flash_loop_edges = true;
  EXPECT_GT(countLabel(following_renderer.render(flashing).labels_3d, kLabelLoopEdge),
            countLabel(picture.labels_3d, kLabelLoopEdge));
}

// A loop whose edge lies far behind the camera (a lap of 8 m along +x, the camera at its end
// looking on along +x): the following camera cannot see it; while it flashes, the overview shows
// the edge, every keyframe and the current camera.
TEST(ViewerRenderer, FlashingLoopPullsTheViewBackToTheWholeMap) {
  ViewerState state = knownState();
  const Quat q_x = so3ExpQuat(Vec3(0.0, M_PI / 2.0, 0.0));  // camera z along world +x
  state.map.keyframes_T_w_c.clear();
  for (int k = 0; k < 9; ++k) state.map.keyframes_T_w_c.push_back(SE3(q_x, Vec3(1.0 * k, 0.0, 0.0)));
  state.map.covisibility.clear();
  state.map.loop_edges = {{0, 1}};  // from the first keyframe to the second, 7-8 m behind
  state.map.points_w.clear();
  state.map.beta.clear();
  state.map.trajectory_w.clear();
  state.frame.T_w_c = SE3(q_x, Vec3(8.0, 0.0, 0.0));
  state.flash_loop_edges = true;

  ViewerOptions options;
  options.panel_width = 320;
  options.panel_height = 240;
  options.loop_overview = false;
  ViewerRenderer following(options);
  EXPECT_EQ(countLabel(following.render(state).labels_3d, kLabelLoopEdge), 0);

  options.loop_overview = true;
  ViewerRenderer overview(options);
  const cv::Mat labels = overview.render(state).labels_3d;
  EXPECT_GT(countLabel(labels, kLabelLoopEdge), 20);
  EXPECT_GT(countLabel(labels, kLabelKeyFrame), 9 * 4);
  EXPECT_GT(countLabel(labels, kLabelCurrentCamera), 4);
  // Nothing the overview frames falls off the panel: the first and last keyframes' centres project inside.
  const OverviewView view = overviewView(state.frame.T_w_c, state.map.keyframes_T_w_c, options.follow_distance_m,
                                         options.follow_height_m, std::atan(0.5 * 240 / (0.6 * 320)));
  for (const Vec3& p_w : {Vec3(0.0, 0.0, 0.0), Vec3(8.0, 0.0, 0.0)}) {
    const Vec3 p_v = view.T_v_w * p_w;
    ASSERT_GT(p_v.z(), 0.0);
    EXPECT_LT(std::abs(0.6 * 320 * p_v.x() / p_v.z()), 160.0);
    EXPECT_LT(std::abs(0.6 * 320 * p_v.y() / p_v.z()), 120.0);
  }
  EXPECT_GT(view.far_m, (view.T_v_w * Vec3(8.0, 0.0, 0.0)).z());
}

TEST(ViewerRenderer, FollowViewLooksAtTheCameraFromBehindAndAbove) {
  const SE3 T_w_c(so3ExpQuat(Vec3(0.0, 0.4, 0.0)), Vec3(1.0, 2.0, 3.0));
  const SE3 T_v_w = followView_T_v_w(T_w_c, 3.0, 1.5);
  const Vec3 camera_in_view = T_v_w * T_w_c.translation();
  EXPECT_NEAR(camera_in_view.x(), 0.0, 1e-9);  // straight ahead, image centre column
  EXPECT_GT(camera_in_view.z(), 2.5);          // in front, about 3 m away
  EXPECT_GT(camera_in_view.y(), 0.0);          // below the view's centre: the view is above it
  const Vec3 eye_w = T_v_w.inverse().translation();
  const Vec3 eye_c = T_w_c.inverse() * eye_w;
  EXPECT_NEAR(eye_c.z(), -3.0, 1e-9);
  EXPECT_NEAR(eye_c.y(), -1.5, 1e-9);  // image up is -y
}


// The replay of a run's files: each frame takes its own pose (none where the run had none), the
// keyframes made up to its time and the trajectory up to it; the status line says "replay".
TEST(RunReplay, EachFrameSeesTheRunUpToItsTime) {
  RunRecording recording;
  for (int i = 0; i < 6; ++i) {
    if (i == 2) continue;  // frame 2 had no pose
    recording.trajectory.push_back({0.1 * i, SE3(Quat::Identity(), Vec3(0.5 * i, 0.0, 0.0))});
  }
  recording.keyframes = {{0.0, SE3(), 0}, {0.3, SE3(Quat::Identity(), Vec3(1.5, 0.0, 0.0)), 1}};
  recording.points = {{Eigen::Vector3f(0.0f, 0.0f, 3.0f), 1.0f}, {Eigen::Vector3f(1.0f, 0.0f, 3.0f), 0.2f}};
  RunReplay replay(recording);
  const cv::Mat image(240, 320, CV_8UC3, cv::Scalar(90, 90, 90));
  cv::Mat mask(240, 320, CV_8UC1, cv::Scalar(0));
  mask(cv::Rect(0, 0, 80, 240)).setTo(255);  // a quarter of the image dynamic

  std::vector<ViewerState> states;
  for (int i = 0; i < 6; ++i) states.push_back(replay.state(i, 0.1 * i, image, mask));
  EXPECT_EQ(replay.framesWithPose(), 5);
  for (int i = 0; i < 6; ++i) {
    const ViewerState& s = states[i];
    EXPECT_TRUE(s.replay);
    EXPECT_EQ(s.frame.index, i);
    EXPECT_EQ(s.frame.has_pose, i != 2) << i;
    if (s.frame.has_pose) {
      EXPECT_NEAR(s.frame.T_w_c.translation().x(), 0.5 * i, 1e-12) << i;
    }
    EXPECT_EQ(s.map.trajectory_w.size(), static_cast<std::size_t>(i < 2 ? i + 1 : i)) << i;
    EXPECT_EQ(s.map.keyframes_T_w_c.size(), i < 3 ? 1u : 2u) << i;
    EXPECT_EQ(s.map.maps, i < 3 ? 1 : 2) << i;
    EXPECT_EQ(s.frame.map, i < 3 ? 0u : 1u) << i;
    EXPECT_EQ(s.map.points_w.size(), 2u);
    EXPECT_FLOAT_EQ(s.map.beta[1], 0.2f);
    EXPECT_NEAR(s.dynamic_share, 0.25, 1e-12);
  }
  EXPECT_EQ(states[2].frame.state, "no pose");

  // Rendered like a live state: the map panel shows the static and the dynamic point.
  ViewerOptions options;
  options.panel_width = 320;
  options.panel_height = 240;
  ViewerRenderer renderer(options);
  const ViewerPicture picture = renderer.render(states[5]);
  EXPECT_GT(cv::countNonZero(picture.labels_3d == kLabelStaticPoint), 0);
  EXPECT_GT(cv::countNonZero(picture.labels_3d == kLabelKeyFrame), 0);
  EXPECT_EQ(cv::countNonZero(picture.labels_3d == kLabelLoopEdge), 0);
}

class ViewerThread : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("ltlo_viewer_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

// 30 Hz frames, Viewer.Fps 10: every third frame is due; each posted one is rendered or dropped,
// and every rendered picture reaches the PNG folder and the video; stop() joins the thread.
TEST_F(ViewerThread, PacesRendersWritesAndJoins) {
  ViewerOptions options;
  options.panel_width = 160;
  options.panel_height = 120;
  ViewerOutputs outputs;
  outputs.png_dir = (dir_ / "png").string();
  outputs.video_path = (dir_ / "viewer.avi").string();
  int map_reads = 0;
  {
    Viewer viewer(options, outputs, [&map_reads](std::uint64_t) {
      ++map_reads;
      return knownState().map;
    });
    int posted = 0;
    for (int i = 0; i < 90; ++i) {
      const double t_s = i / 30.0;
      if (!viewer.due(t_s)) continue;
      ViewerFrame frame = knownState().frame;
      frame.index = i;
      frame.t_s = t_s;
      viewer.post(std::move(frame));
      ++posted;
    }
    EXPECT_EQ(posted, 30);
    viewer.stop();
    const ViewerCounts counts = viewer.counts();
    EXPECT_EQ(counts.posted, 30u);
    EXPECT_EQ(counts.rendered + counts.dropped, counts.posted);
    EXPECT_GE(counts.rendered, 1u);
    EXPECT_EQ(counts.png_frames, counts.rendered);
    EXPECT_EQ(counts.video_frames, counts.posted);  // one per posted state, dropped ones held
    EXPECT_EQ(counts.video_held, counts.dropped);
    EXPECT_EQ(static_cast<std::uint64_t>(map_reads), counts.rendered);
    int pngs = 0;
    for (const fs::directory_entry& entry : fs::directory_iterator(outputs.png_dir)) {
      const cv::Mat png = cv::imread(entry.path().string());
      EXPECT_EQ(png.size(), cv::Size(320, 120)) << entry.path();
      ++pngs;
    }
    EXPECT_EQ(static_cast<std::uint64_t>(pngs), counts.rendered);
    // The last frame posted is never dropped: stop() renders what is waiting.
    EXPECT_TRUE(fs::exists(fs::path(outputs.png_dir) / "000087.png"));
    viewer.stop();  // idempotent
  }
  EXPECT_GT(fs::file_size(outputs.video_path), 1000u);
  for (const std::string& name : runningNamedThreads()) EXPECT_EQ(name.find("viewer"), std::string::npos) << name;
}

// States dropped while the viewer is busy still get their video frames: the picture before them
// stands in for each, so the video has one frame per posted state (the run's pace). The viewer is
// held inside its first picture's map read while four more states are posted: the first three are
// replaced (dropped), the fifth is rendered; the video holds pictures 0, 0, 0, 0, 0 and 5.
TEST_F(ViewerThread, VideoRepeatsThePreviousPictureForEachDroppedState) {
  ViewerOptions options;
  options.panel_width = 160;
  options.panel_height = 120;
  ViewerOutputs outputs;
  outputs.video_path = (dir_ / "viewer.avi").string();
  std::mutex mutex;
  std::condition_variable changed;
  bool inside_first = false, release = false;
  int reads = 0;
  Viewer viewer(options, outputs, [&](std::uint64_t) {
    std::unique_lock<std::mutex> lock(mutex);
    if (reads++ == 0) {
      inside_first = true;
      changed.notify_all();
      changed.wait(lock, [&] { return release; });
    }
    return knownState().map;
  });
  auto postAt = [&](int index, bool dynamic_left) {
    ViewerFrame frame = knownState().frame;
    frame.index = index;
    frame.t_s = index / 10.0;
    frame.dynamic_mask.setTo(dynamic_left ? 255 : 0);  // pictures 0 and 5 differ in the tint
    viewer.post(std::move(frame));
  };
  postAt(0, true);
  {
    std::unique_lock<std::mutex> lock(mutex);
    changed.wait(lock, [&] { return inside_first; });
  }
  for (int index = 1; index <= 5; ++index) postAt(index, false);
  {
    std::lock_guard<std::mutex> lock(mutex);
    release = true;
  }
  changed.notify_all();
  viewer.stop();
  const ViewerCounts counts = viewer.counts();
  EXPECT_EQ(counts.posted, 6u);
  EXPECT_EQ(counts.rendered, 2u);
  EXPECT_EQ(counts.dropped, 4u);
  EXPECT_EQ(counts.video_frames, 6u);
  EXPECT_EQ(counts.video_held, 4u);
  cv::VideoCapture video(outputs.video_path);
  ASSERT_TRUE(video.isOpened());
  std::vector<cv::Mat> frames;
  for (cv::Mat picture; video.read(picture);) frames.push_back(picture.clone());
  ASSERT_EQ(frames.size(), 6u);
  for (int k = 1; k <= 4; ++k) EXPECT_EQ(cv::norm(frames[k], frames[0], cv::NORM_INF), 0.0) << "frame " << k;
  EXPECT_GT(cv::norm(frames[5], frames[0], cv::NORM_L1), 0.0);
}

// A frame the viewer is done with comes back for the next post with its buffers: the colour
// image it rendered (and one replaced before it was taken) keeps its allocation.
TEST_F(ViewerThread, RendersAndReplacedFramesComeBackWithTheirBuffers) {
  ViewerOptions options;
  options.panel_width = 160;
  options.panel_height = 120;
  Viewer viewer(options, ViewerOutputs(), [](std::uint64_t) { return knownState().map; });
  EXPECT_TRUE(viewer.recycledFrame().color_bgr.empty());  // nothing has come back yet
  ViewerFrame frame = knownState().frame;
  const std::uint8_t* const pixels = frame.color_bgr.data;
  viewer.post(std::move(frame));
  viewer.stop();  // renders the waiting frame, then joins
  ASSERT_EQ(viewer.counts().rendered, 1u);
  ViewerFrame recycled = viewer.recycledFrame();
  EXPECT_EQ(recycled.color_bgr.data, pixels);
  const cv::Mat next(240, 320, CV_8UC3, cv::Scalar(1, 2, 3));
  next.copyTo(recycled.color_bgr);  // what ViewerFeed does: same size, no new allocation
  EXPECT_EQ(recycled.color_bgr.data, pixels);
  EXPECT_EQ(recycled.color_bgr.at<cv::Vec3b>(10, 10), cv::Vec3b(1, 2, 3));
  EXPECT_TRUE(viewer.recycledFrame().color_bgr.empty());  // handed out once
}

TEST_F(ViewerThread, UnopenableOutputsAreBadInputNamingTheFile) {
  ViewerOptions options;
  ViewerOutputs outputs;
  outputs.video_path = (dir_ / "viewer.mkv").string();
  try {
    Viewer viewer(options, outputs, [](std::uint64_t) { return ViewerMap(); });
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(outputs.video_path), std::string::npos) << e.what();
  }
  // A folder that does not exist yet is created; one that cannot be (a file is in its way) is bad input.
  outputs.video_path = (dir_ / "new" / "folder" / "viewer.avi").string();
  { Viewer viewer(options, outputs, [](std::uint64_t) { return ViewerMap(); }); }
  EXPECT_TRUE(fs::exists(outputs.video_path));
  { std::ofstream(dir_ / "a_file") << "x"; }
  outputs.video_path = (dir_ / "a_file" / "viewer.avi").string();
  try {
    Viewer viewer(options, outputs, [](std::uint64_t) { return ViewerMap(); });
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(outputs.video_path), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ltlo::viewer
