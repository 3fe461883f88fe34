#include "test_images.h"

#include <filesystem>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace ltlo::features::test {

std::vector<std::string> existingFiles(const std::vector<std::string>& candidates) {
  std::vector<std::string> found;
  for (const std::string& path : candidates) {
    if (std::filesystem::exists(path)) found.push_back(path);
  }
  return found;
}

cv::Mat texturedVgaImage() {
  static const cv::Mat cached = []() -> cv::Mat {  // decoded once per test binary
    const std::vector<std::string> found = existingFiles({
        "/usr/share/backgrounds/picosdeeuropa_by_Aitzol_Berasategi.jpg",
        "/usr/share/backgrounds/mate/nature/Garden.jpg",
        "/usr/share/backgrounds/mate/nature/RainDrops.jpg",
    });
    if (found.empty()) return {};
    const cv::Mat photo = cv::imread(found.front(), cv::IMREAD_REDUCED_GRAYSCALE_2);
    if (photo.empty()) return {};
    const int w = std::min(photo.cols, photo.rows * 4 / 3);
    const int h = w * 3 / 4;
    cv::Mat vga;
    cv::resize(photo(cv::Rect((photo.cols - w) / 2, (photo.rows - h) / 2, w, h)), vga, cv::Size(640, 480), 0, 0,
               cv::INTER_AREA);
    return vga;
  }();
  return cached.clone();
}

cv::Mat warp(const cv::Mat& image, const cv::Matx33d& H) {
  cv::Mat out;
  cv::warpPerspective(image, out, cv::Mat(H), image.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  return out;
}

}  // namespace ltlo::features::test
