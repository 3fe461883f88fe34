#pragma once
/// What the live viewer draws (issue 30): plain copies of the run's state, so rendering never holds
/// a lock of the map, the tracker or System. Two parts with two producers:
///   ViewerFrame  the tracking thread's frame (its colour image, keypoint classes, pose, status),
///                copied at most Viewer.Fps times a second of sequence time;
///   ViewerMap    the active map (points with beta, keyframes, covisibility and loop edges, the
///                trajectory so far), read by the viewer thread itself through the map's
///                thread-safe API just before it renders (System::viewerMap).
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"

namespace ltlo::viewer {

/// How a keypoint of the current frame was used.
enum class KeypointClass : std::uint8_t {
  kUntracked,  ///< static, no map point matched (or an outlier)
  kTracked,    ///< matched to a map point and an inlier of the pose
  kDynamic,    ///< in a cluster the segmentation calls dynamic (never used for the pose)
};

struct ViewerKeypoint {
  float u = 0.0f, v = 0.0f;  ///< pixel in the input image
  KeypointClass kind = KeypointClass::kUntracked;
};

/// The current frame as tracking left it.
struct ViewerFrame {
  int index = 0;                   ///< input frame number (0-based)
  double t_s = 0.0;                ///< sequence time
  cv::Mat color_bgr;               ///< the input colour image (a copy), CV_8UC3
  cv::Mat dynamic_mask;            ///< CV_8U, 255 = dynamic, at any resolution (scaled to the image)
  std::vector<ViewerKeypoint> keypoints;
  bool has_pose = false;
  SE3 T_w_c;                       ///< in the world of `map`
  std::uint64_t map = 0;           ///< map the frame was tracked in
  std::string state;               ///< tracking state name (tracking::trackingStateName)
  bool tracked = false;            ///< tracked against the map (the current camera drawn white, else red)
  bool imu_carried = false;        ///< posed by the IMU prediction alone
};

/// The map around the current frame, in its world frame.
struct ViewerMap {
  std::uint64_t map = 0;
  std::vector<Eigen::Vector3f> points_w;
  std::vector<float> beta;                  ///< static score of each point, [0, 1]
  std::vector<SE3> keyframes_T_w_c;
  std::vector<std::pair<int, int>> covisibility;  ///< indices into keyframes_T_w_c
  std::vector<std::pair<int, int>> loop_edges;    ///< indices into keyframes_T_w_c
  std::vector<Eigen::Vector3f> trajectory_w;      ///< every posed frame of this map so far, in order
  int keyframes_all_maps = 0;
  int maps = 0;
  int loops = 0;
  int merges = 0;
};

/// One picture's worth of state, plus what the viewer adds (processing rate, a flash after a loop).
struct ViewerState {
  ViewerFrame frame;
  ViewerMap map;
  double fps = 0.0;              ///< frames processed per second of wall time, recently
  double dynamic_share = 0.0;    ///< share of the image the segmentation calls dynamic
  bool flash_loop_edges = false; ///< a loop or merge landed since the previous picture
  /// A replay of a finished run (run_replay.h): the status line shows no processing rate and no
  /// loop or merge counts (the run's files do not hold them per frame).
  bool replay = false;
};

}  // namespace ltlo::viewer
