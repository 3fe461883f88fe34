#pragma once
// Generated depth scene shared by the segmentation tests and benchmark: a slanted far plane on the
// left (about 3 m), a fronto-parallel plane at 2 m on the right, a box face at 1 m in front of
// both, a band without depth along the top and a hole in the far plane.
#include <opencv2/core/mat.hpp>

#include "ltlo/core/camera.h"

namespace ltlo::segmentation::test {

enum Surface : uint8_t { kFarPlane = 0, kNearPlane = 1, kBox = 2, kNoDepth = 255 };

struct SyntheticDepth {
  PinholeCamera camera;
  cv::Mat depth_m;  // CV_32F, 0 = no depth
  cv::Mat surface;  // CV_8U, Surface of each pixel
};

inline SyntheticDepth makeTwoPlanesAndBox(int width, int height) {
  SyntheticDepth scene;
  const double f = 0.82 * width;
  scene.camera = PinholeCamera(f, f, 0.5 * (width - 1), 0.5 * (height - 1), width, height);
  scene.depth_m = cv::Mat(height, width, CV_32F, cv::Scalar(0.0f));
  scene.surface = cv::Mat(height, width, CV_8U, cv::Scalar(kNoDepth));
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const double x = u / static_cast<double>(width), y = v / static_cast<double>(height);
      float depth_m;
      Surface surface;
      if (y < 0.08 || (x > 0.1 && x < 0.2 && y > 0.6 && y < 0.75)) {
        continue;  // no depth: top band and a hole in the far plane
      } else if (x > 0.35 && x < 0.65 && y > 0.3 && y < 0.8) {
        depth_m = 1.0f;
        surface = kBox;
      } else if (x < 0.5) {
        depth_m = static_cast<float>(3.0 + 0.6 * (x - 0.25));  // slanted: 2.85 .. 3.15 m
        surface = kFarPlane;
      } else {
        depth_m = 2.0f;
        surface = kNearPlane;
      }
      scene.depth_m.at<float>(v, u) = depth_m;
      scene.surface.at<uint8_t>(v, u) = surface;
    }
  }
  return scene;
}

}  // namespace ltlo::segmentation::test
