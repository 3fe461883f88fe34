// Hindsight masks (issue 32): a frame's mask relabelled against the final static map. A box that the
// online mask calls static, with static map points seen behind it from where the frame stands, turns
// dynamic and the wall around it stays static; the same points seen only from far to the side (the
// parallax of a static object in front of a wall) change nothing; points the frame sees past do not
// outvote the points behind the surface; a region the online mask calls dynamic turns static where the
// static points lie on its surface.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include <opencv2/core.hpp>

#include "ltlo/core/camera_model.h"
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

}  // namespace
}  // namespace ltlo::system
