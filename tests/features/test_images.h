#pragma once
// Real photographs for the feature tests: the Debian wallpaper packages installed by
// scripts/setup.sh (gnome-backgrounds, mate-backgrounds, lomiri-wallpapers, sway-backgrounds).
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace ltlo::features::test {

/// Existing paths among `candidates` (absolute), in the given order.
std::vector<std::string> existingFiles(const std::vector<std::string>& candidates);

/// A textured VGA grey image: the centre 4:3 window of a photograph scaled to 640x480; empty if
/// no candidate photograph is installed.
cv::Mat texturedVgaImage();

/// Applies H (3x3, maps source pixels to destination pixels) to a VGA image, same size out.
cv::Mat warp(const cv::Mat& image, const cv::Matx33d& H);

}  // namespace ltlo::features::test
