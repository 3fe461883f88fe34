#pragma once
// Texture collages for the simulated room (private to ltlo_sim).
#include <opencv2/core/mat.hpp>
#include <random>
#include <string>
#include <vector>

namespace ltlo::sim {

/// Reads the known photographs under `dir` (fixed order, downscaled on load); empty when none.
std::vector<cv::Mat> loadPhotos(const std::string& dir, std::vector<std::string>* paths);

/// Procedural stand-ins for photos: coloured multi-scale value noise with blobs and edges.
std::vector<cv::Mat> proceduralPhotos(int count, std::mt19937_64& rng);

/// A collage of `size`: base photo `base` (cropped to cover), then framed crops of other photos
/// pasted at several scales (large posters down to small labels), so corners exist at every scale.
cv::Mat makeCollage(const std::vector<cv::Mat>& photos, int base, cv::Size size,
                    std::mt19937_64& rng);

}  // namespace ltlo::sim
