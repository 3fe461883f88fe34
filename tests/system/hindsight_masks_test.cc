// Hindsight masks (issue 32): a frame's mask relabelled against the final static map. A box that the
// online mask calls static, with static map points seen behind it from where the frame stands, turns
// dynamic and the wall around it stays static; the same points seen only from far to the side (the
// parallax of a static object in front of a wall) change nothing; points the frame sees past do not
// outvote the points behind the surface; a region the online mask calls dynamic turns static where the
// static points lie on its surface. Free space: without any map point, a box where two keyframes saw the
// wall turns dynamic; keyframes that saw the box there, one keyframe alone, or the frame's own depth do not;
// among many keyframes a frame asks at most Seg.HindsightFreeSpaceMaxViews, those that saw its surface.
// Keyframes that saw a wall see through a leaf 6 cm in front of it with Seg.HindsightFreeSpaceTolerance,
// unless the depth noise measured in the run's images (the second difference of inverse depth) covers 6 cm.
// The folder pass: a leaf that comes to rest where only frames between the keyframes saw the wall turns
// dynamic with Seg.HindsightFreeSpaceFrameInterval, and stays as it was with the keyframes alone.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "ltlo/core/camera_model.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/system/hindsight_masks.h"

namespace ltlo::system {
namespace {

constexpr int kWidth = 160, kHeight = 120;
constexpr double kWallDepth = 3.0, kBoxDepth = 1.0;
const cv::Rect kBox(40, 30, 80, 60);  // the box's pixels, raw image

class HindsightRelabel : public ::testing::Test {
 protected:
  HindsightRelabel()
      : camera_(PinholeCamera(120.0, 120.0, 79.5, 59.5, kWidth, kHeight), LensDistortion()),
        // A pose away from the identity, so a frame mix-up shows.
        T_w_c_(SE3::exp((Vec6() << 0.1, -0.2, 0.05, 0.5, 0.2, -0.3).finished())) {
    options_.clusters.num_clusters = 8;
    options_.label_width = kWidth / 2;
    options_.label_height = kHeight / 2;
    depth_ = cv::Mat(kHeight, kWidth, CV_32F, cv::Scalar(kWallDepth));
    depth_(kBox).setTo(kBoxDepth);
  }

  /// The world point at raw pixel (u, v) and depth z of the frame.
  Vec3 pointAt(double u, double v, double z) const {
    const PinholeCamera& k = camera_.pinhole();
    return T_w_c_ * Vec3((u - k.cx()) / k.fx() * z, (v - k.cy()) / k.fy() * z, z);
  }

  /// Static wall points on a grid, each observed from `observer_c` (camera frame of the frame).
  void addWallPoints(bool behind_box, const Vec3& observer_c) {
    for (int v = 4; v < kHeight; v += 8) {
      for (int u = 4; u < kWidth; u += 8) {
        if (kBox.contains(cv::Point(u, v)) != behind_box) continue;
        MapPointRecord point;
        point.p_w = pointAt(u, v, kWallDepth);
        point.beta = 0.9;
        point.observer_centres_w.push_back(T_w_c_ * observer_c);
        points_.push_back(point);
      }
    }
  }

  /// Share of the dynamic (255) pixels inside and outside the box after relabelling an all-static mask.
  std::pair<double, double> relabelledShares(HindsightFrameResult* result = nullptr) {
    cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
    HindsightRelabeller relabeller(camera_, options_);
    const HindsightFrameResult r = relabeller.relabel(depth_, T_w_c_, points_, &mask);
    if (result != nullptr) *result = r;
    cv::Mat outside = mask.clone();
    outside(kBox).setTo(0);
    const double inside_share = cv::countNonZero(mask(kBox)) / static_cast<double>(kBox.area());
    const double outside_share = cv::countNonZero(outside) / static_cast<double>(kWidth * kHeight - kBox.area());
    return {inside_share, outside_share};
  }

  CameraModel camera_;
  SE3 T_w_c_;
  HindsightMaskOptions options_;
  cv::Mat depth_;
  std::vector<MapPointRecord> points_;
};

TEST_F(HindsightRelabel, ABoxWithTheStaticWallMappedBehindItTurnsDynamic) {
  addWallPoints(/*behind_box=*/false, Vec3::Zero());
  addWallPoints(/*behind_box=*/true, Vec3(0.02, 0.0, 0.0));  // seen from (almost) where the frame stands
  HindsightFrameResult result;
  const auto [inside, outside] = relabelledShares(&result);
  EXPECT_GT(inside, 0.95);
  EXPECT_LT(outside, 0.01);
  EXPECT_GT(result.regions_flipped, 0);
}

TEST_F(HindsightRelabel, PointsHiddenByParallaxSayNothingAboutTheObjectInFront) {
  // The same wall points behind the "box" (now a static cupboard), seen only from 1.5 m to the side:
  // their rays pass 1 m beside the cupboard's front, so no surface of the frame stood in their way.
  addWallPoints(/*behind_box=*/false, Vec3::Zero());
  addWallPoints(/*behind_box=*/true, Vec3(1.5, 0.0, 0.0));
  const auto [inside, outside] = relabelledShares();
  EXPECT_EQ(inside, 0.0);
  EXPECT_EQ(outside, 0.0);
}

TEST_F(HindsightRelabel, PointsTheFrameSeesPastDoNotOutvoteThePointsBehindIt) {
  addWallPoints(/*behind_box=*/true, Vec3::Zero());
  // Three times as many points floating in front of the box (the frame sees past them): counted as
  // agreeing votes they would hold the box static.
  const std::size_t behind = points_.size();
  for (std::size_t i = 0; i < 3 * behind; ++i) {
    MapPointRecord point = points_[i % behind];
    const Vec3 p_c = T_w_c_.inverse() * point.p_w;
    point.p_w = T_w_c_ * (p_c * (0.6 / p_c.z()));
    points_.push_back(point);
  }
  const auto [inside, outside] = relabelledShares();
  EXPECT_GT(inside, 0.95);
  EXPECT_LT(outside, 0.01);
}

TEST_F(HindsightRelabel, AFewPointsAreNotEnough) {
  addWallPoints(/*behind_box=*/true, Vec3::Zero());
  points_.resize(static_cast<std::size_t>(options_.min_points) - 1);
  EXPECT_EQ(relabelledShares().first, 0.0);
}

TEST_F(HindsightRelabel, ADynamicMaskTurnsStaticOnlyWhereTheStaticMapLiesOnItsSurface) {
  // An all-dynamic mask: the wall, whose static points lie on its surface, turns static; the box, with
  // static points behind it seen through it, stays dynamic. Without Seg.HindsightToStatic nothing changes.
  addWallPoints(/*behind_box=*/false, Vec3::Zero());
  addWallPoints(/*behind_box=*/true, Vec3::Zero());
  for (const bool to_static : {true, false}) {
    options_.to_static = to_static;
    cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(255));
    HindsightRelabeller relabeller(camera_, options_);
    const HindsightFrameResult result = relabeller.relabel(depth_, T_w_c_, points_, &mask);
    cv::Mat outside = mask.clone();
    outside(kBox).setTo(0);
    const double outside_share = cv::countNonZero(outside) / static_cast<double>(kWidth * kHeight - kBox.area());
    EXPECT_EQ(cv::countNonZero(mask(kBox)), kBox.area()) << "to_static " << to_static;
    if (to_static) {
      EXPECT_LT(outside_share, 0.01);
      EXPECT_GT(result.regions_to_static, 0);
    } else {
      EXPECT_EQ(outside_share, 1.0);
      EXPECT_EQ(result.regions_to_static, 0);
    }
  }
}

/// Relabels an all-static mask without map points, against keyframe depths: `view_depths` seen from the
/// frame's pose moved by `offsets_c` (camera frame), at times 1, 2, ... s. Returns the box's and the
/// rest's dynamic shares.
std::pair<double, double> freeSpaceShares(const CameraModel& camera, const HindsightMaskOptions& options,
                                          const SE3& T_w_c, const cv::Mat& depth,
                                          const std::vector<std::pair<cv::Mat, Vec3>>& views_c,
                                          HindsightFrameResult* result = nullptr, double t_s = 0.0) {
  std::vector<FreeSpaceView> views;
  double t = 1.0;
  for (const auto& [view_depth, offset_c] : views_c) {
    views.push_back(FreeSpaceView::fromDepth(view_depth, T_w_c * SE3(Quat::Identity(), offset_c), t, 4));
    t += 1.0;
  }
  cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
  HindsightRelabeller relabeller(camera, options);
  const HindsightFrameResult r = relabeller.relabel(depth, T_w_c, {}, &mask, views, t_s);
  if (result != nullptr) *result = r;
  cv::Mat outside = mask.clone();
  outside(kBox).setTo(0);
  return {cv::countNonZero(mask(kBox)) / static_cast<double>(kBox.area()),
          cv::countNonZero(outside) / static_cast<double>(kWidth * kHeight - kBox.area())};
}

TEST_F(HindsightRelabel, ABoxWhereKeyFramesSawTheWallTurnsDynamicWithoutAnyPoint) {
  // Two keyframes 20 cm to either side saw the bare wall (a plane at 3 m in the frame's camera frame,
  // so at 3 m in theirs too) where the box now stands: the box is dynamic, texture or not.
  const cv::Mat wall(kHeight, kWidth, CV_32F, cv::Scalar(kWallDepth));
  HindsightFrameResult result;
  const auto [inside, outside] =
      freeSpaceShares(camera_, options_, T_w_c_, depth_, {{wall, Vec3(0.2, 0.0, 0.0)}, {wall, Vec3(-0.2, 0.05, 0.0)}},
                      &result);
  EXPECT_GT(inside, 0.95);
  EXPECT_LT(outside, 0.01);
  EXPECT_GT(result.regions_free_space, 0);
  EXPECT_EQ(result.regions_flipped, result.regions_free_space);
  // Off (Seg.HindsightFreeSpace 0): nothing changes.
  options_.free_space = false;
  EXPECT_EQ(freeSpaceShares(camera_, options_, T_w_c_, depth_, {{wall, Vec3(0.2, 0.0, 0.0)}, {wall, Vec3(-0.2, 0.05, 0.0)}})
                .first,
            0.0);
}

TEST_F(HindsightRelabel, KeyFramesThatSawTheBoxThereOrOneKeyFrameAloneChangeNothing) {
  const cv::Mat wall(kHeight, kWidth, CV_32F, cv::Scalar(kWallDepth));
  // Keyframes from the frame's own viewpoint and 5 cm beside it that saw the box where it is now: no
  // surface of the frame stood in free space (the box's edge, seen a pixel aside, is no exception).
  cv::Mat beside = depth_.clone();
  const auto [inside_same, outside_same] =
      freeSpaceShares(camera_, options_, T_w_c_, depth_, {{depth_, Vec3::Zero()}, {beside, Vec3(0.05, 0.0, 0.0)}});
  EXPECT_EQ(inside_same, 0.0);
  EXPECT_EQ(outside_same, 0.0);
  // One keyframe that saw the wall, with Seg.HindsightFreeSpaceViews 2: not enough.
  EXPECT_EQ(freeSpaceShares(camera_, options_, T_w_c_, depth_, {{wall, Vec3(0.2, 0.0, 0.0)}, {depth_, Vec3::Zero()}})
                .first,
            0.0);
  // The frame's own time among the views (its own depth is no other keyframe's): skipped, so again one.
  EXPECT_EQ(freeSpaceShares(camera_, options_, T_w_c_, depth_, {{wall, Vec3(0.2, 0.0, 0.0)}, {wall, Vec3::Zero()}},
                            nullptr, /*t_s=*/2.0)
                .first,
            0.0);
  options_.free_space_views = 1;
  EXPECT_GT(freeSpaceShares(camera_, options_, T_w_c_, depth_, {{wall, Vec3(0.2, 0.0, 0.0)}, {depth_, Vec3::Zero()}})
                .first,
            0.95);
}

TEST_F(HindsightRelabel, PointsOnABoxThatKeyFramesSawThroughDoNotTurnItStatic) {
  // An all-dynamic mask and static points lying on the box's surface (made on the box while it stood
  // there and never seen again): alone they turn the box static. Two keyframes that saw the wall where
  // the box stands veto it: the box stays dynamic, and the wall, seen where it is, still turns static.
  for (int v = 4; v < kHeight; v += 8) {
    for (int u = 4; u < kWidth; u += 8) {
      MapPointRecord point;
      point.p_w = pointAt(u, v, kBox.contains(cv::Point(u, v)) ? kBoxDepth : kWallDepth);
      point.beta = 0.9;
      point.observer_centres_w.push_back(T_w_c_.translation());
      points_.push_back(point);
    }
  }
  const cv::Mat wall(kHeight, kWidth, CV_32F, cv::Scalar(kWallDepth));
  std::vector<FreeSpaceView> views;
  views.push_back(FreeSpaceView::fromDepth(wall, T_w_c_ * SE3(Quat::Identity(), Vec3(0.2, 0.0, 0.0)), 5.0, 4));
  views.push_back(FreeSpaceView::fromDepth(wall, T_w_c_ * SE3(Quat::Identity(), Vec3(-0.2, 0.05, 0.0)), 6.0, 4));
  const auto box_dynamic_share = [&](const std::vector<FreeSpaceView>& asked, double* outside_share) {
    cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(255));
    HindsightRelabeller relabeller(camera_, options_);
    relabeller.relabel(depth_, T_w_c_, points_, &mask, asked, 0.0);
    cv::Mat outside = mask.clone();
    outside(kBox).setTo(0);
    *outside_share = cv::countNonZero(outside) / static_cast<double>(kWidth * kHeight - kBox.area());
    return cv::countNonZero(mask(kBox)) / static_cast<double>(kBox.area());
  };
  double outside = 1.0;
  EXPECT_LT(box_dynamic_share({}, &outside), 0.05);  // the points alone: static
  EXPECT_LT(outside, 0.01);
  EXPECT_EQ(box_dynamic_share(views, &outside), 1.0);  // seen through: stays dynamic
  EXPECT_LT(outside, 0.01);
  options_.free_space = false;  // Seg.HindsightFreeSpace 0: no veto
  EXPECT_LT(box_dynamic_share(views, &outside), 0.05);
}

TEST_F(HindsightRelabel, AmongManyKeyFramesAFrameAsksAtMostTheBoundThoseThatSawItsSurface) {
  // 40 keyframes at rest beside the frame saw the box where it stands (seen, not through), then two
  // keyframes 20 cm to either side saw the wall there, and 30 turned 95-99 deg away (inside the 100 deg the
  // test allows, but their field holds none of the frame's surface). With
  // Seg.HindsightFreeSpaceMaxViews 32 the frame asks 32 and the two that saw through are among them.
  const cv::Mat wall(kHeight, kWidth, CV_32F, cv::Scalar(kWallDepth));
  std::vector<FreeSpaceView> views;
  const auto add = [&](const cv::Mat& depth, const SE3& T_c_v) {
    views.push_back(FreeSpaceView::fromDepth(depth, T_w_c_ * T_c_v, 1.0 + static_cast<double>(views.size()), 4));
  };
  for (int k = 0; k < 40; ++k) add(depth_, SE3(Quat::Identity(), Vec3(0.001 * k, 0.0, 0.0)));
  add(wall, SE3(Quat::Identity(), Vec3(0.2, 0.0, 0.0)));
  add(wall, SE3(Quat::Identity(), Vec3(-0.2, 0.05, 0.0)));
  for (int k = 0; k < 30; ++k) {
    add(wall, SE3(Quat(Eigen::AngleAxisd((95.0 + 0.15 * k) * M_PI / 180.0, Vec3::UnitY())), Vec3::Zero()));
  }
  const auto relabel = [&](int max_views, HindsightFrameResult* result) {
    options_.free_space_max_views = max_views;
    cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
    HindsightRelabeller relabeller(camera_, options_);
    *result = relabeller.relabel(depth_, T_w_c_, {}, &mask, views, 0.0);
    return cv::countNonZero(mask(kBox)) / static_cast<double>(kBox.area());
  };
  HindsightFrameResult bounded, all, one;
  EXPECT_GT(relabel(32, &bounded), 0.95);
  EXPECT_EQ(bounded.views_asked, 32);
  // All of them (0) give the same box, asking every keyframe that faces the frame (72).
  EXPECT_GT(relabel(0, &all), 0.95);
  EXPECT_EQ(all.views_asked, 72);
  EXPECT_EQ(all.regions_free_space, bounded.regions_free_space);
  // Asking only the best one: a single keyframe saw through, not the two needed.
  EXPECT_EQ(relabel(1, &one), 0.0);
  EXPECT_EQ(one.views_asked, 1);
}

TEST_F(HindsightRelabel, AKeyFrameFacingAwaySeesNothingThroughTheLensPolynomialsFold) {
  // A D435-like radial-tangential lens (k1 0.015, k2 -0.005): its polynomial turns back beyond the field,
  // and rays 75.5-76.5 deg off the axis distort into the image's middle. Keyframes turned 74-78 deg away
  // (every 0.25 deg, to either side) that saw a wall at 3 m do not see the box, so nothing changes, even
  // with one view enough.
  LensDistortion lens;
  lens.model = LensModel::kRadTan;
  lens.k1 = 0.015;
  lens.k2 = -0.005;
  const CameraModel distorted(camera_.pinhole(), lens);
  const cv::Mat wall(kHeight, kWidth, CV_32F, cv::Scalar(kWallDepth));
  std::vector<FreeSpaceView> views;
  for (double angle_deg = 74.0; angle_deg <= 78.0; angle_deg += 0.25) {
    for (const double sign : {1.0, -1.0}) {
      const SE3 T_w_v =
          T_w_c_ * SE3(Quat(Eigen::AngleAxisd(sign * angle_deg * M_PI / 180.0, Vec3::UnitY())), Vec3::Zero());
      views.push_back(FreeSpaceView::fromDepth(wall, T_w_v, 1.0 + static_cast<double>(views.size()), 4));
    }
  }
  // The fold is there: the box's centre ray, seen from the view 76 deg away, lands inside the raw image.
  const FreeSpaceView& at_76 = views[16];
  const Vec3 centre_v = at_76.R_c_w * (T_w_c_ * Vec3(0.0, 0.0, kBoxDepth)) + at_76.t_c_w;
  const Vec2 folded = distorted.project(centre_v);
  ASSERT_GT(centre_v.z(), 0.0);
  ASSERT_TRUE(folded.x() >= 0.0 && folded.x() < kWidth && folded.y() >= 0.0 && folded.y() < kHeight)
      << folded.transpose();
  options_.free_space_views = 1;
  cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
  HindsightRelabeller relabeller(distorted, options_);
  const HindsightFrameResult result = relabeller.relabel(depth_, T_w_c_, {}, &mask, views, 0.0);
  EXPECT_EQ(cv::countNonZero(mask), 0);
  EXPECT_EQ(result.regions_free_space, 0);
}

TEST_F(HindsightRelabel, KeyFramesThatSawTheWallSeeThroughALeafSixCentimetresInFrontOfIt) {
  // A closed door leaf 6 cm in front of a wall at 2 m, within the V_i gap there (0.15 m), beyond the
  // free-space tolerance (Seg.HindsightFreeSpaceTolerance 0.02 + 3 x 0.0025 x 2^2 = 0.05 m). Two keyframes
  // saw the bare wall: with the gap they did not see through the leaf, with the tolerance they did. The
  // wall is seen where it is either way, and a leaf 3 cm in front of it (within the tolerance) is not seen
  // through.
  constexpr double kWall = 2.0;
  const cv::Mat wall(kHeight, kWidth, CV_32F, cv::Scalar(kWall));
  options_.depth_noise_m = 0.0025;
  for (const double leaf_gap_m : {0.06, 0.03}) {
    depth_.setTo(kWall);
    depth_(kBox).setTo(kWall - leaf_gap_m);
    for (const double tolerance_m : {0.0, 0.02}) {
      options_.free_space_tolerance_m = tolerance_m;
      const auto [leaf, rest] =
          freeSpaceShares(camera_, options_, T_w_c_, depth_, {{wall, Vec3(0.2, 0.0, 0.0)}, {wall, Vec3(-0.2, 0.05, 0.0)}});
      EXPECT_LT(rest, 0.01) << "leaf " << leaf_gap_m << " m in front, tolerance " << tolerance_m;
      if (tolerance_m > 0.0 && leaf_gap_m > 0.05) {
        EXPECT_GT(leaf, 0.95) << "leaf " << leaf_gap_m << " m in front, tolerance " << tolerance_m;
      } else {
        EXPECT_EQ(leaf, 0.0) << "leaf " << leaf_gap_m << " m in front, tolerance " << tolerance_m;
      }
    }
  }
}

TEST(MeasureDepthNoise, TheSecondDifferenceOfInverseDepthOnPlanesIsTheNoise) {
  // A slanted floor-like plane (1-3.5 m down the image) with a box 0.5 m in front of it over a quarter of
  // the image and a hole: noise-free, the measure is nil (the plane's inverse depth is linear along a row,
  // the box's edges are outliers); with sigma(z) = k z^2, k = 4 mm, it reads k within 10 %.
  const segmentation::DepthKMeansOptions clusters;
  const PinholeCamera k(300.0, 300.0, 159.5, 119.5, 320, 240);
  const Vec3 normal = Vec3(0.1, -0.8, -0.3).normalized();  // plane n.x = d in the camera frame
  const double d = -1.2;
  std::vector<cv::Mat> clean, noisy;
  cv::RNG rng(7);
  for (int frame = 0; frame < 3; ++frame) {
    cv::Mat depth(k.height(), k.width(), CV_32F);
    for (int r = 0; r < depth.rows; ++r) {
      for (int c = 0; c < depth.cols; ++c) {
        const Vec3 ray((c - k.cx()) / k.fx(), (r - k.cy()) / k.fy(), 1.0);
        double z = d / normal.dot(ray);
        if (z <= 0.0 || z > 3.5) z = 3.5;
        if (r > 60 && r < 180 && c > 80 + 10 * frame && c < 240) z -= 0.5;  // the box
        depth.at<float>(r, c) = static_cast<float>(z);
      }
    }
    depth(cv::Rect(10, 10, 20, 20)).setTo(0.0f);  // a hole
    clean.push_back(depth.clone());
    for (int r = 0; r < depth.rows; ++r) {
      for (int c = 0; c < depth.cols; ++c) {
        float& z = depth.at<float>(r, c);
        if (z > 0.0f) z += static_cast<float>(rng.gaussian(0.004 * z * z));
      }
    }
    noisy.push_back(depth);
  }
  EXPECT_LT(measureDepthNoise(clean, clusters), 1e-4);
  EXPECT_NEAR(measureDepthNoise(noisy, clusters), 0.004, 0.0004);
  EXPECT_EQ(measureDepthNoise({}, clusters), 0.0);
}

TEST_F(HindsightRelabel, AMeasuredNoiseAboveTheConfiguredRaisesTheFreeSpaceTolerance) {
  // The leaf 6 cm in front of a wall at 2 m, two keyframes that saw the wall: seen through with
  // Recon.DepthNoise 2.5 mm (tolerance 0.05 m at 2 m); a measured noise under it changes nothing, one of
  // 5 mm (0.08 m at 2 m) makes the leaf part of the wall.
  constexpr double kWall = 2.0;
  const cv::Mat wall(kHeight, kWidth, CV_32F, cv::Scalar(kWall));
  depth_.setTo(kWall);
  depth_(kBox).setTo(kWall - 0.06);
  options_.free_space_tolerance_m = 0.02;
  options_.depth_noise_m = 0.0025;
  const auto leaf_seen_through = [&](double measured_noise_m) {
    options_.measured_noise_m = measured_noise_m;
    return freeSpaceShares(camera_, options_, T_w_c_, depth_, {{wall, Vec3(0.2, 0.0, 0.0)}, {wall, Vec3(-0.2, 0.05, 0.0)}});
  };
  EXPECT_GT(leaf_seen_through(0.0).first, 0.95);
  EXPECT_GT(leaf_seen_through(0.0015).first, 0.95);
  const auto [leaf, wall_share] = leaf_seen_through(0.005);
  EXPECT_EQ(leaf, 0.0);
  EXPECT_EQ(wall_share, 0.0);
}

TEST(FreeSpaceView, EachPixelIsTheNearestDepthOfTheBlocksAroundAndUnknownBesideAHole) {
  cv::Mat depth(16, 16, CV_32F, cv::Scalar(3.0));
  depth(cv::Rect(0, 0, 4, 4)).setTo(1.0);   // a near block in the top-left corner
  depth.at<float>(13, 1) = 0.0f;            // a pixel without depth in the bottom-left block
  depth(cv::Rect(12, 12, 4, 4)).setTo(0.0f);  // the bottom-right block has none
  const FreeSpaceView view = FreeSpaceView::fromDepth(depth, SE3(), 0.0, 4);
  ASSERT_EQ(view.depth_m.cols, 4);
  ASSERT_EQ(view.depth_m.rows, 4);
  EXPECT_FLOAT_EQ(view.depth_m.at<float>(0, 0), 1.0f);
  EXPECT_FLOAT_EQ(view.depth_m.at<float>(1, 1), 1.0f);   // the near block is its neighbour
  EXPECT_FLOAT_EQ(view.depth_m.at<float>(0, 2), 3.0f);
  EXPECT_FLOAT_EQ(view.depth_m.at<float>(3, 0), 3.0f);   // a block's nearest depth skips a pixel without depth
  EXPECT_FLOAT_EQ(view.depth_m.at<float>(3, 3), 0.0f);   // a block without depth, and those beside it, unknown
  EXPECT_FLOAT_EQ(view.depth_m.at<float>(2, 2), 0.0f);
  EXPECT_FLOAT_EQ(view.depth_m.at<float>(1, 3), 3.0f);
  EXPECT_TRUE(view.axis_w.isApprox(Vec3::UnitZ()));
}

/// A sequence folder (DATA_FORMAT.md) of a camera standing still before a wall at kWallDepth: frames
/// 0..3 see the bare wall (a door open), frames 4..7 the leaf at rest at kBoxDepth over kBox. Online
/// masks all static. The run's final poses: every frame at T_w_c in map 0; its one keyframe is frame 5.
class HindsightFolderPass : public ::testing::Test {
 protected:
  static constexpr int kFrames = 8;
  static constexpr double kFramePeriodS = 0.5;
  static constexpr int kKeyFrame = 5;

  void SetUp() override {
    namespace fs = std::filesystem;
    dir_ = fs::temp_directory_path() / ("ltlo_hindsight_folder_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    for (const char* sub : {"rgb", "depth", "online", "final"}) fs::create_directories(dir_ / sub);
    std::ofstream rgb_list(dir_ / "rgb.txt"), depth_list(dir_ / "depth.txt");
    const SE3 T_w_c(SE3::exp((Vec6() << 0.1, -0.2, 0.05, 0.5, 0.2, -0.3).finished()));
    for (int i = 0; i < kFrames; ++i) {
      char stamp[32];
      std::snprintf(stamp, sizeof(stamp), "%.6f", i * kFramePeriodS);
      cv::Mat depth_mm(kHeight, kWidth, CV_16UC1, cv::Scalar(kWallDepth * 1000.0));
      if (i >= 4) depth_mm(kBox).setTo(kBoxDepth * 1000.0);
      ASSERT_TRUE(cv::imwrite((dir_ / "depth" / (std::string(stamp) + ".png")).string(), depth_mm));
      ASSERT_TRUE(cv::imwrite((dir_ / "rgb" / (std::string(stamp) + ".png")).string(),
                              cv::Mat(kHeight, kWidth, CV_8UC3, cv::Scalar(90, 120, 150))));
      ASSERT_TRUE(cv::imwrite((dir_ / "online" / (std::string(stamp) + ".png")).string(),
                              cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(0))));
      rgb_list << stamp << " rgb/" << stamp << ".png\n";
      depth_list << stamp << " depth/" << stamp << ".png\n";
      trajectory_.push_back({i * kFramePeriodS, T_w_c, /*tracked=*/true, map::MapId(0)});
    }
    KeyFrameRecord keyframe;
    keyframe.t_s = kKeyFrame * kFramePeriodS;
    keyframe.T_w_c = T_w_c;
    keyframe.id = 0;
    keyframe.map = 0;
    keyframes_.push_back(keyframe);
    std::ofstream calib(dir_ / "calib.yaml");
    calib << "%YAML:1.0\nCamera.fx: 120.0\nCamera.fy: 120.0\nCamera.cx: 79.5\nCamera.cy: 59.5\n"
             "Camera.width: 160\nCamera.height: 120\nCamera.fps: 2\nDepthMapFactor: 1000.0\n";
    options_.clusters.num_clusters = 8;
    options_.label_width = kWidth / 2;
    options_.label_height = kHeight / 2;
    options_.num_threads = 2;
    options_.rejudge.frame.width = kWidth / 2;
    options_.rejudge.frame.height = kHeight / 2;
    options_.rejudge.clusters.num_clusters = 8;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  /// Runs the pass; returns the leaf's and the rest's dynamic shares in each frame's written mask.
  std::vector<std::pair<double, double>> run(HindsightMaskResult* result, const std::vector<FramePose>& online = {}) {
    io::SequenceReaderOptions reader_options;
    reader_options.masks_dir = (dir_ / "online").string();
    reader_options.read_ground_truth = false;
    const io::SequenceReader reader = io::SequenceReader::open(dir_.string(), reader_options);
    const CameraModel camera(PinholeCamera(120.0, 120.0, 79.5, 59.5, kWidth, kHeight), LensDistortion());
    std::filesystem::remove_all(dir_ / "final");
    *result = writeHindsightMasks(reader, trajectory_, keyframes_, map::MapId(0), {}, camera, options_,
                                  (dir_ / "final").string(), online);
    std::vector<std::pair<double, double>> shares;
    for (int i = 0; i < kFrames; ++i) {
      char stamp[32];
      std::snprintf(stamp, sizeof(stamp), "%.6f", i * kFramePeriodS);
      const cv::Mat mask = cv::imread((dir_ / "final" / (std::string(stamp) + ".png")).string(), cv::IMREAD_UNCHANGED);
      EXPECT_FALSE(mask.empty()) << stamp;
      if (mask.empty()) return shares;
      cv::Mat outside = mask.clone();
      outside(kBox).setTo(0);
      shares.emplace_back(cv::countNonZero(mask(kBox)) / static_cast<double>(kBox.area()),
                          cv::countNonZero(outside) / static_cast<double>(kWidth * kHeight - kBox.area()));
    }
    return shares;
  }

  std::filesystem::path dir_;
  std::vector<FramePose> trajectory_;
  std::vector<KeyFrameRecord> keyframes_;
  HindsightMaskOptions options_;
};

TEST_F(HindsightFolderPass, ALeafAtRestWhereOnlyFramesSawTheWallTurnsDynamicWithFrameViews) {
  // Keyframes only: the one keyframe saw the leaf where it rests, so nothing changes.
  options_.free_space_frame_interval_s = 0.0;
  HindsightMaskResult result;
  std::vector<std::pair<double, double>> shares = run(&result);
  ASSERT_EQ(shares.size(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(result.free_space_views, 1);
  EXPECT_EQ(result.free_space_frame_views, 0);
  for (const auto& [leaf, rest] : shares) {
    EXPECT_EQ(leaf, 0.0);
    EXPECT_EQ(rest, 0.0);
  }
  // A frame every 0.5 s: the seven frames that are not the keyframe's are views too; frames 0..3 saw the
  // wall where the leaf rests in frames 4..7, which turn dynamic there and nowhere else.
  options_.free_space_frame_interval_s = kFramePeriodS;
  shares = run(&result);
  ASSERT_EQ(shares.size(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(result.free_space_views, 1);
  EXPECT_EQ(result.free_space_frame_views, kFrames - 1);
  for (int i = 0; i < kFrames; ++i) {
    EXPECT_EQ(shares[static_cast<std::size_t>(i)].second, 0.0) << "frame " << i;
    if (i < 4) {
      EXPECT_EQ(shares[static_cast<std::size_t>(i)].first, 0.0) << "frame " << i;
    } else {
      EXPECT_GT(shares[static_cast<std::size_t>(i)].first, 0.95) << "frame " << i;
    }
  }
  // A frame asks no frame view within kFrameViewMinGapS (1 s): with Seg.HindsightFreeSpaceViews 4, frame 4
  // (t = 2 s) has three views of the wall at least 1 s away (frames 0..2; frame 3 is 0.5 s away), frame 7
  // four (frames 0..3).
  options_.free_space_views = 4;
  shares = run(&result);
  ASSERT_EQ(shares.size(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(shares[4].first, 0.0);
  EXPECT_GT(shares[7].first, 0.95);
  options_.free_space_views = 2;
  // One frame every 1.25 s: frames 0, 3 and 6 (t = 0, 1.5, 3), the first two of which saw the wall:
  // Seg.HindsightFreeSpaceViews 2 still holds for frame 7.
  options_.free_space_frame_interval_s = 1.25;
  shares = run(&result);
  ASSERT_EQ(shares.size(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(result.free_space_frame_views, 3);
  EXPECT_GT(shares[7].first, 0.95);
  // One every 1.75 s: frames 0 and 4 (t = 0, 2); one view of the wall is not enough.
  options_.free_space_frame_interval_s = 1.75;
  shares = run(&result);
  ASSERT_EQ(shares.size(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(result.free_space_frame_views, 2);
  EXPECT_EQ(shares[7].first, 0.0);
}

// Re-judging (hindsight_rejudge.h) asks the online poses: a frame is judged again where its online motion
// from its reference frame (here the frame before: 0.5 s apart, more than the 0.3-s baseline) moved its
// surface from where the final poses put it, or where the two online poses lie in different maps.
TEST_F(HindsightFolderPass, AFrameIsJudgedAgainWhereItsOnlineMotionDisagreesWithTheFinalPoses) {
  HindsightMaskResult result;
  run(&result);  // no online trajectory: nothing to compare
  EXPECT_EQ(result.frames_rejudged, 0);
  std::vector<FramePose> online = trajectory_;
  run(&result, online);  // the online poses are the final ones
  EXPECT_EQ(result.frames_relabelled, kFrames);
  EXPECT_EQ(result.frames_rejudged, 0);
  // Frames 4..7 online 10 cm to the side: only frame 4's motion from frame 3 is wrong (2 label pixels on
  // the wall 3 m away, 6 on the leaf 1 m away).
  for (int i = 4; i < kFrames; ++i) {
    online[static_cast<std::size_t>(i)].T_w_c = SE3(Quat::Identity(), Vec3(0.1, 0.0, 0.0)) * trajectory_[static_cast<std::size_t>(i)].T_w_c;
  }
  run(&result, online);
  EXPECT_EQ(result.frames_rejudged, 1);
  // Frame 6 began a new online map: its motion from frame 5 is unknown.
  for (int i = 6; i < kFrames; ++i) online[static_cast<std::size_t>(i)].map = map::MapId(1);
  const std::vector<std::pair<double, double>> shares = run(&result, online);
  EXPECT_EQ(result.frames_rejudged, 2);
  // The online masks called everything static, and re-judging only turns dynamic pixels static.
  ASSERT_EQ(shares.size(), static_cast<std::size_t>(kFrames));
  for (const auto& [leaf, rest] : shares) EXPECT_EQ(rest, 0.0);
  // Off: the online judgement stands.
  options_.rejudge.enable = false;
  run(&result, online);
  EXPECT_EQ(result.frames_rejudged, 0);
}

}  // namespace
}  // namespace ltlo::system
