#pragma once
/// ORB features: FAST corners on a scale pyramid, spread evenly by a quadtree, oriented by the
/// intensity centroid, described by a rotated 256-bit BRIEF with our own fixed sampling pattern.
#include <array>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace ltlo::features {

/// 256-bit binary descriptor; test i is bit i % 64 of word i / 64. The same type as bow::Descriptor,
/// so OrbFeatures::descriptors goes straight into bow::Vocabulary::transform.
using Descriptor = std::array<std::uint64_t, 4>;

/// Extractor parameters; the caller builds them (from settings) and passes them by const&.
struct OrbOptions {
  int num_features = 1000;    ///< target number of features per image (ORBextractor.nFeatures)
  double scale_factor = 1.2;  ///< scale between pyramid levels, > 1 (ORBextractor.scaleFactor)
  int num_levels = 8;         ///< pyramid levels, in [1, 32] (ORBextractor.nLevels)
  int ini_th_fast = 20;       ///< FAST threshold tried first in each cell (ORBextractor.iniThFAST)
  int min_th_fast = 7;        ///< fallback FAST threshold for cells with no corner (ORBextractor.minThFAST)
};

/// One ORB keypoint; coordinates in level-0 pixels.
struct Keypoint {
  float x_px = 0.0f;         ///< column, level-0 pixels
  float y_px = 0.0f;         ///< row, level-0 pixels
  float angle_deg = 0.0f;    ///< orientation of the intensity centroid, [0, 360)
  float response = 0.0f;     ///< FAST score at detection
  int octave = 0;            ///< pyramid level the corner was found on
};

struct OrbFeatures {
  std::vector<Keypoint> keypoints;
  std::vector<Descriptor> descriptors;  ///< descriptors[i] belongs to keypoints[i]
};

/// Stateless after construction: extract() is const and thread-safe.
class OrbExtractor {
 public:
  /// Throws ltlo::ConfigError on out-of-range options.
  explicit OrbExtractor(const OrbOptions& options);

  /// Features of an 8-bit grey image (CV_8UC1). Deterministic: the same image gives the same
  /// keypoints and descriptors, in the same order.
  OrbFeatures extract(const cv::Mat& image_gray) const;

  const OrbOptions& options() const { return options_; }
  int numLevels() const { return options_.num_levels; }
  /// scale_factor^level, the size of one level-`level` pixel in level-0 pixels.
  const std::vector<float>& scaleFactors() const { return scale_factors_; }
  /// sigma^2 of a keypoint's position error per level (scale^2), and 1 / sigma^2, for optimiser weights.
  const std::vector<float>& levelSigma2() const { return level_sigma2_; }
  const std::vector<float>& invLevelSigma2() const { return inv_level_sigma2_; }

 private:
  OrbOptions options_;
  std::vector<float> scale_factors_;
  std::vector<float> level_sigma2_;
  std::vector<float> inv_level_sigma2_;
  std::vector<int> features_per_level_;
  std::vector<int> circle_half_width_;  ///< half-width of the orientation disc per row offset 0..15
  /// BRIEF sampling pattern, 512 points (level pixels): test i compares point 2i with point 2i + 1.
  std::vector<float> pattern_x_;
  std::vector<float> pattern_y_;
};

}  // namespace ltlo::features
