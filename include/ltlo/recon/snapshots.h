#pragma once
/// Headless pictures of a surfel model (OSMesa through ltlo::render, no display, no GPU):
///   bird_eye.png        from above, the estimated and ground-truth trajectories drawn on it and
///                       the positions of the three path views marked
///   path_1..3.png       from just behind the camera at 1/4, 1/2 and 3/4 of the trajectory
///   orbit_0..7.png      eight views around the model from 35 deg above the horizon; surfels
///                       facing away are culled, so walls open like a doll's house
///   user_view.png       from a given eye towards a given target (when asked for)
///   frames.png          for four frames: the input RGB beside the static/dynamic overlay
///   contact_sheet.png   all of the above as labelled thumbnails
/// Surfels are discs of their radius, coloured and lit by a headlight by their normal.
/// "Up" is the normal of the plane the trajectory moves in (ground robots), signed by the cameras'
/// up direction, or the cameras' mean up direction when the motion is not planar.
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <vector>

#include "ltlo/core/camera.h"
#include "ltlo/core/eigen_types.h"
#include "ltlo/io/trajectory_io.h"
#include "ltlo/recon/surfel.h"

namespace ltlo::recon {

/// A viewpoint in the world frame of the surfels.
struct UserView {
  Vec3 eye_w;
  Vec3 target_w;
};

struct SnapshotOptions {
  int width = 960;  ///< every rendered view, px
  int height = 720;
  double fov_deg = 60.0;  ///< horizontal field of view of the path, orbit and user views
  std::optional<UserView> user_view;
};

/// One input frame for frames.png.
struct OverlayFrame {
  int index = 0;
  double t_s = 0.0;
  cv::Mat colour_bgr;    ///< CV_8UC3
  cv::Mat depth_m;       ///< CV_32F; pixels without depth are dimmed in the overlay
  cv::Mat dynamic_mask;  ///< CV_8UC1, 255 = dynamic; empty = every pixel static (no segmentation)
};

struct SnapshotScene {
  const std::vector<Surfel>* surfels = nullptr;
  io::Trajectory estimate;  ///< T_w_c of the fusion
  std::string estimate_label = "estimated trajectory";
  io::Trajectory ground_truth;  ///< in the estimate's world frame; empty = not drawn
  std::vector<OverlayFrame> overlays;
  PinholeCamera camera;  ///< the input camera (overlay sizes)
  std::string title;     ///< top line of the contact sheet
};

/// Renders and writes the pictures into `dir` (created); returns their paths in the order above.
/// Throws InputError when a file cannot be written, std::runtime_error when OSMesa fails.
std::vector<std::string> writeSnapshots(const SnapshotScene& scene, const SnapshotOptions& options,
                                        const std::string& dir);

/// The world's up direction as described above (unit); +z of the world when the trajectory has
/// fewer than 3 poses.
Vec3 estimateUpDirection(const io::Trajectory& trajectory);

/// A pinhole camera of `fov_deg` horizontal field of view for a width x height image (its pose:
/// render::lookAt).
PinholeCamera viewCamera(int width, int height, double fov_deg);

}  // namespace ltlo::recon
