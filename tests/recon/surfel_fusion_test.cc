// SurfelFusion on ray-cast planar scenes: one layer from two poses, free-space removal of a
// moved object, dynamic masks, unstable surfels, and surfels.ply round trips.
#include "ltlo/recon/surfel_fusion.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <tuple>

#include "ltlo/core/errors.h"
#include "ltlo/recon/surfel_ply.h"

namespace ltlo::recon {
namespace {

// 160 x 120 camera, 120 px focal length: the fusion grid (Recon.Downsample 2) is 80 x 60.
PinholeCamera testCamera() { return PinholeCamera(120.0, 120.0, 79.5, 59.5, 160, 120); }

/// A rectangle: centre, unit normal, in-plane unit axis u (v = normal x u), half extents.
struct Rect {
  Vec3 centre;
  Vec3 normal;
  Vec3 axis_u;
  double half_u = 1.0;
  double half_v = 1.0;
  bool dynamic = false;
  cv::Vec3b bgr{120, 140, 160};
};

// Ray-casts the rectangles (nearest hit) into a frame; depth noise sigma(z) = noise_at_1m z^2.
FusionFrame renderFrame(const std::vector<Rect>& scene, const SE3& T_w_c, double t_s,
                        double noise_at_1m = 0.0, std::mt19937* rng = nullptr) {
  const PinholeCamera cam = testCamera();
  FusionFrame frame;
  frame.t_s = t_s;
  frame.T_w_c = T_w_c;
  frame.depth_m = cv::Mat(cam.height(), cam.width(), CV_32F, cv::Scalar(0.0f));
  frame.colour_bgr = cv::Mat(cam.height(), cam.width(), CV_8UC3, cv::Scalar(0, 0, 0));
  frame.dynamic_mask = cv::Mat(cam.height(), cam.width(), CV_8UC1, cv::Scalar(0));
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Mat3 R_w_c = T_w_c.rotationMatrix();
  for (int v = 0; v < cam.height(); ++v) {
    for (int u = 0; u < cam.width(); ++u) {
      const Vec3 ray_w = R_w_c * cam.backProject(Vec2(u, v), 1.0);  // z = 1 in the camera
      double best = 1e9;
      const Rect* hit = nullptr;
      for (const Rect& r : scene) {
        const double denom = r.normal.dot(ray_w);
        if (std::abs(denom) < 1e-9) continue;
        const double s = r.normal.dot(r.centre - T_w_c.translation()) / denom;
        if (s <= 0.0 || s >= best) continue;
        const Vec3 d = T_w_c.translation() + s * ray_w - r.centre;
        const Vec3 axis_v = r.normal.cross(r.axis_u);
        if (std::abs(d.dot(r.axis_u)) > r.half_u || std::abs(d.dot(axis_v)) > r.half_v) continue;
        best = s;
        hit = &r;
      }
      if (hit == nullptr) continue;
      double z = best;
      if (rng != nullptr) z += noise_at_1m * z * z * gauss(*rng);
      frame.depth_m.at<float>(v, u) = static_cast<float>(z);
      frame.colour_bgr.at<cv::Vec3b>(v, u) = hit->bgr;
      if (hit->dynamic) frame.dynamic_mask.at<uint8_t>(v, u) = 255;
    }
  }
  return frame;
}

Rect wallAt(double z_m) { return Rect{Vec3(0, 0, z_m), Vec3(0, 0, -1), Vec3(1, 0, 0), 6.0, 6.0}; }

SE3 yawedPose(double x_m, double yaw_deg) {
  const double a = yaw_deg * M_PI / 180.0;
  Mat3 R;
  R << std::cos(a), 0, std::sin(a), 0, 1, 0, -std::sin(a), 0, std::cos(a);
  return SE3(R, Vec3(x_m, 0, 0));
}

// Surfels whose centre projects at least `margin_px` inside the image of camera pose T_w_c.
bool insideView(const Surfel& s, const SE3& T_w_c, double margin_px) {
  const PinholeCamera cam = testCamera();
  const Vec3 p_c = T_w_c.inverse() * s.position_w.cast<double>();
  return p_c.z() > 0.1 && cam.isInImage(cam.project(p_c), margin_px);
}

struct LayerStats {
  int in_overlap = 0;
  double rms_m = 0.0;
  double max_m = 0.0;
};

LayerStats layerStats(const std::vector<Surfel>& surfels, double plane_z_m, const SE3& A,
                      const SE3& B) {
  LayerStats stats;
  double sum2 = 0.0;
  for (const Surfel& s : surfels) {
    const double d = std::abs(s.position_w.z() - plane_z_m);
    sum2 += d * d;
    stats.max_m = std::max(stats.max_m, d);
    if (insideView(s, A, 10.0) && insideView(s, B, 10.0)) ++stats.in_overlap;
  }
  stats.rms_m = surfels.empty() ? 0.0 : std::sqrt(sum2 / surfels.size());
  return stats;
}

// Fuses 8 frames from pose A, then 8 from pose B whose depth sees the wall `b_offset_m` farther
// (0 = consistent views; < 0 a misregistered second view that sees it nearer, so the first layer
// is hidden behind it rather than seen through); returns the overlap counts after A and after
// A + B, with the layer statistics at the end.
struct TwoPoseResult {
  int overlap_after_a = 0;
  LayerStats after_b;
};
TwoPoseResult fuseTwoPoses(double b_offset_m) {
  const SE3 A = yawedPose(0.0, 0.0);
  const SE3 B = yawedPose(0.3, -10.0);
  SurfelFusion fusion(testCamera(), ReconOptions());
  std::mt19937 rng(11);
  const double noise_at_1m = 0.0015;  // the simulator's structured-light model
  double t_s = 0.0;
  for (int k = 0; k < 8; ++k, t_s += 1.0 / 15.0) {
    fusion.integrate(renderFrame({wallAt(2.0)}, A, t_s, noise_at_1m, &rng));
  }
  TwoPoseResult result;
  result.overlap_after_a = layerStats(fusion.allSurfels(), 2.0, A, B).in_overlap;
  for (int k = 0; k < 8; ++k, t_s += 1.0 / 15.0) {
    fusion.integrate(renderFrame({wallAt(2.0 + b_offset_m)}, B, t_s, noise_at_1m, &rng));
  }
  result.after_b = layerStats(fusion.allSurfels(), 2.0, A, B);
  return result;
}

TEST(SurfelFusion, PlaneSeenFromTwoPosesFusesToOneLayer) {
  const TwoPoseResult r = fuseTwoPoses(0.0);
  // Pose A alone: about one surfel per fusion pixel of the overlap (a few hundred).
  ASSERT_GT(r.overlap_after_a, 300);
  // The second view re-finds those surfels instead of adding a layer: at most 15 % more (new
  // surfels where the second view's pixels fall between discs of the first).
  EXPECT_LT(r.after_b.in_overlap, 1.15 * r.overlap_after_a);
  // Thickness: depth noise at 2 m is 6 mm per pixel, 3 mm after the 2 x 2 block mean, and less
  // once averaged over frames: RMS < 1.5 mm (half the single-block sigma), every surfel within
  // 9 mm (3 sigma of one block).
  EXPECT_LT(r.after_b.rms_m, 0.0015);
  EXPECT_LT(r.after_b.max_m, 0.009);
}

TEST(SurfelFusion, MisregisteredSecondViewMakesASecondLayer) {
  // The same views with the second 8 cm nearer (beyond the 4 cm association window at 2 m): the
  // count and thickness checks above see it.
  const TwoPoseResult r = fuseTwoPoses(-0.08);
  EXPECT_GT(r.after_b.in_overlap, 1.7 * r.overlap_after_a);
  EXPECT_GT(r.after_b.max_m, 0.07);
}

// A box face 1 m in front of a wall for 1 s, then gone for 1 s.
std::vector<Surfel> fuseMovedObject(const ReconOptions& options, bool mark_dynamic,
                                    int* surfels_on_box_at_1s) {
  Rect box{Vec3(0, 0, 2.0), Vec3(0, 0, -1), Vec3(1, 0, 0), 0.4, 0.3, mark_dynamic};
  SurfelFusion fusion(testCamera(), options);
  auto on_box = [](const std::vector<Surfel>& surfels) {
    int n = 0;
    for (const Surfel& s : surfels) n += s.position_w.z() < 2.5f;
    return n;
  };
  double t_s = 0.0;
  for (int k = 0; k < 15; ++k, t_s += 1.0 / 15.0) {
    fusion.integrate(renderFrame({wallAt(3.0), box}, SE3(), t_s));
  }
  *surfels_on_box_at_1s = on_box(fusion.stableSurfels());
  for (int k = 0; k < 15; ++k, t_s += 1.0 / 15.0) {
    fusion.integrate(renderFrame({wallAt(3.0)}, SE3(), t_s));
  }
  return fusion.allSurfels();
}

TEST(SurfelFusion, FreeSpaceViolationsRemoveAMovedObject) {
  int on_box_at_1s = 0;
  const std::vector<Surfel> surfels = fuseMovedObject(ReconOptions(), false, &on_box_at_1s);
  // 0.8 x 0.6 m at 2 m = 48 x 36 px = 24 x 18 fusion pixels: ~430 stable surfels on the box.
  EXPECT_GT(on_box_at_1s, 300);
  int on_box = 0, on_wall_behind = 0;
  for (const Surfel& s : surfels) {
    if (s.position_w.z() < 2.5f) ++on_box;
    if (std::abs(s.position_w.z() - 3.0f) < 0.01f && std::abs(s.position_w.x()) < 0.3f &&
        std::abs(s.position_w.y()) < 0.2f) {
      ++on_wall_behind;
    }
  }
  EXPECT_EQ(on_box, 0);
  // The wall behind it is filled in: 0.6 x 0.4 m at 3 m = 12 x 8 fusion pixels.
  EXPECT_GT(on_wall_behind, 80);
}

TEST(SurfelFusion, WithoutFreeSpaceRemovalTheMovedObjectStays) {
  ReconOptions options;
  options.free_space_votes = 0;
  int on_box_at_1s = 0;
  const std::vector<Surfel> surfels = fuseMovedObject(options, false, &on_box_at_1s);
  int on_box = 0;
  for (const Surfel& s : surfels) on_box += s.position_w.z() < 2.5f;
  EXPECT_EQ(on_box, on_box_at_1s);  // stable surfels are never removed as unstable
}

TEST(SurfelFusion, DynamicPixelsAreNotFused) {
  int on_box_at_1s = 0;
  ReconOptions options;
  options.free_space_votes = 0;  // nothing may be created, so nothing needs removing
  const std::vector<Surfel> surfels = fuseMovedObject(options, true, &on_box_at_1s);
  EXPECT_EQ(on_box_at_1s, 0);
  int on_box = 0;
  for (const Surfel& s : surfels) on_box += s.position_w.z() < 2.5f;
  EXPECT_EQ(on_box, 0);
}

TEST(SurfelFusion, UnstableSurfelsGoAfterTheWindow) {
  // An object seen in one frame only (a glitch) in front of a wall; free-space removal off, so
  // only the stability rule can remove it.
  ReconOptions options;
  options.free_space_votes = 0;
  options.unstable_time_s = 1.0;
  Rect glitch{Vec3(0, 0, 2.0), Vec3(0, 0, -1), Vec3(1, 0, 0), 0.3, 0.3};
  SurfelFusion fusion(testCamera(), options);
  auto count_glitch = [&] {
    int n = 0;
    for (const Surfel& s : fusion.allSurfels()) n += s.position_w.z() < 2.5f;
    return n;
  };
  fusion.integrate(renderFrame({wallAt(3.0), glitch}, SE3(), 0.0));
  const int created = count_glitch();
  EXPECT_GT(created, 200);
  double t_s = 0.1;
  for (; t_s < 0.95; t_s += 0.1) fusion.integrate(renderFrame({wallAt(3.0)}, SE3(), t_s));
  EXPECT_EQ(count_glitch(), created);  // still inside the window
  fusion.integrate(renderFrame({wallAt(3.0)}, SE3(), 1.05));
  EXPECT_EQ(count_glitch(), 0);
  // The wall seen 11 times near the image centre is stable.
  EXPECT_GT(fusion.stableSurfels().size(), 1000u);
}

// 20 frames of a wall with a box for the first 10, the camera yawing; `threads` split the
// fusion, `prepared` measures each frame with prepare() (reusing one PreparedFrame) first.
std::vector<Surfel> fuseYawingScene(int threads, bool prepared) {
  SurfelFusion fusion(testCamera(), ReconOptions(), threads);
  PreparedFrame measurement;
  Rect box{Vec3(0.2, 0, 2.0), Vec3(0, 0, -1), Vec3(1, 0, 0), 0.4, 0.3};
  std::mt19937 rng(5);
  double t_s = 0.0;
  for (int k = 0; k < 20; ++k, t_s += 0.1) {
    const SE3 pose = yawedPose(0.02 * k, -1.0 * k);
    const FusionFrame frame =
        renderFrame(k < 10 ? std::vector<Rect>{wallAt(3.0), box} : std::vector<Rect>{wallAt(3.0)},
                    pose, t_s, 0.0015, &rng);
    if (prepared) {
      fusion.prepare(frame, &measurement);
      fusion.integrate(frame, measurement);
    } else {
      fusion.integrate(frame);
    }
  }
  std::vector<Surfel> surfels = fusion.allSurfels();
  std::sort(surfels.begin(), surfels.end(), [](const Surfel& a, const Surfel& b) {
    return std::make_tuple(a.position_w.x(), a.position_w.y(), a.position_w.z()) <
           std::make_tuple(b.position_w.x(), b.position_w.y(), b.position_w.z());
  });
  return surfels;
}

void expectSameSurfels(const std::vector<Surfel>& a, const std::vector<Surfel>& b) {
  ASSERT_GT(a.size(), 2000u);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].position_w, b[i].position_w) << i;
    ASSERT_EQ(a[i].normal_w, b[i].normal_w) << i;
    ASSERT_EQ(a[i].radius_m, b[i].radius_m) << i;
    ASSERT_EQ(a[i].confidence, b[i].confidence) << i;
  }
}

TEST(SurfelFusion, ThreadsDoNotChangeTheResult) {
  expectSameSurfels(fuseYawingScene(1, false), fuseYawingScene(3, false));
}

TEST(SurfelFusion, PreparedFramesFuseLikeWholeFrames) {
  // The loader threads' path (measure on one thread, fuse on two) against integrate(frame).
  expectSameSurfels(fuseYawingScene(1, false), fuseYawingScene(2, true));
}

TEST(SurfelPly, RoundTripKeepsEveryProperty) {
  std::vector<Surfel> surfels(3);
  for (int i = 0; i < 3; ++i) {
    surfels[i].position_w = Eigen::Vector3f(0.5f * i, -1.25f, 3.0f + i);
    surfels[i].normal_w = Eigen::Vector3f(0.0f, 0.6f, -0.8f);
    surfels[i].colour_rgb = Eigen::Vector3f(10.0f * i, 200.4f, 255.0f);
    surfels[i].radius_m = 0.004f * (i + 1);
    surfels[i].confidence = 7.5f + i;
  }
  const std::string path =
      (std::filesystem::temp_directory_path() / ("surfels_" + std::to_string(::getpid()) + ".ply"))
          .string();
  writeSurfelPly(path, surfels);
  const std::vector<Surfel> back = readSurfelPly(path);
  ASSERT_EQ(back.size(), surfels.size());
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(back[i].position_w, surfels[i].position_w);
    EXPECT_EQ(back[i].normal_w, surfels[i].normal_w);
    EXPECT_EQ(back[i].colour_rgb, Eigen::Vector3f(10.0f * i, 200.0f, 255.0f));  // uchar
    EXPECT_EQ(back[i].radius_m, surfels[i].radius_m);
    EXPECT_EQ(back[i].confidence, surfels[i].confidence);
  }
  // 11 properties, 35 bytes per surfel after the header.
  const auto size = std::filesystem::file_size(path);
  std::filesystem::resize_file(path, size - 10);
  try {
    readSurfelPly(path);
    ADD_FAILURE() << "truncated file accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": truncated: 2 of 3 surfels"), std::string::npos)
        << e.what();
  }
  std::filesystem::remove(path);
}

// A corrupt vertex count is refused before anything is allocated for it; a non-finite value is
// refused naming the surfel (check_surfels and the snapshots grid the positions).
TEST(SurfelPly, RefusesCountsBeyondTheFileAndNonFiniteValues) {
  std::vector<Surfel> surfels(2);
  surfels[0].radius_m = surfels[1].radius_m = 0.01f;
  const std::string path =
      (std::filesystem::temp_directory_path() / ("surfels_bad_" + std::to_string(::getpid()) + ".ply"))
          .string();
  writeSurfelPly(path, surfels);
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const auto rewrite = [&](const std::string& content) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << content;
  };
  const auto message = [&]() -> std::string {
    try {
      readSurfelPly(path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "accepted";
  };
  std::string huge = bytes;
  huge.replace(huge.find("element vertex 2"), 16, "element vertex 4000000000000");
  rewrite(huge);
  EXPECT_NE(message().find(path + ": truncated: 2 of 4000000000000 surfels"), std::string::npos)
      << message();

  std::string nan = bytes;
  const std::size_t body = nan.find("end_header\n") + 11;
  const float not_a_number = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&nan[body + 35 + 4], &not_a_number, 4);  // surfel 1, y (little-endian hosts)
  rewrite(nan);
  EXPECT_NE(message().find(path + ": surfel 1 has a value that is not finite"), std::string::npos)
      << message();
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace ltlo::recon
