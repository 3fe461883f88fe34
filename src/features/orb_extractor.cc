#include "ltlo/features/orb_extractor.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "ltlo/core/errors.h"
#include "quadtree.h"

namespace ltlo::features {
namespace {

constexpr int kPatchRadius = 15;     // orientation disc and descriptor pattern radius, level pixels
constexpr int kEdge = 16;            // keypoints keep this distance to the level border (disc + rounding)
constexpr int kFastMargin = 3;       // FAST's Bresenham circle radius
constexpr int kCellSize = 32;        // FAST threshold cells, level pixels
constexpr std::uint32_t kPatternSeed = 0x4C544C4Fu;  // "LTLO": fixes the BRIEF sampling pattern
constexpr double kPatternSigma = 31.0 / 5.0;         // isotropic Gaussian pairs (BRIEF's G II layout)

/// 256 point pairs, i.i.d. Gaussian around the keypoint, clipped to the disc of radius 15 so that a
/// rotated pattern stays inside it. Generated from mt19937 with our own Box-Muller transform, so
/// the pattern is the same with every standard library.
std::vector<cv::Point> makePattern() {
  std::mt19937 rng(kPatternSeed);
  const auto uniform = [&rng]() { return (static_cast<double>(rng()) + 0.5) / 4294967296.0; };
  const auto gaussianPoint = [&]() {
    while (true) {
      const double r = std::sqrt(-2.0 * std::log(uniform())) * kPatternSigma;
      const double phi = 2.0 * M_PI * uniform();
      const cv::Point p(static_cast<int>(std::lround(r * std::cos(phi))),
                        static_cast<int>(std::lround(r * std::sin(phi))));
      if (p.x * p.x + p.y * p.y <= kPatchRadius * kPatchRadius) return p;
    }
  };
  std::vector<cv::Point> pattern;
  while (pattern.size() < 512) {
    const cv::Point a = gaussianPoint();
    const cv::Point b = gaussianPoint();
    if (a == b) continue;
    pattern.push_back(a);
    pattern.push_back(b);
  }
  return pattern;
}

/// Orientation of the intensity centroid m = (m10, m01) over the disc of radius 15, degrees.
float centroidAngleDeg(const cv::Mat& level, int x, int y, const std::vector<int>& half_width) {
  int m10 = 0;
  int m01 = 0;
  const std::uint8_t* centre = level.ptr<std::uint8_t>(y) + x;
  const int step = static_cast<int>(level.step1());
  for (int u = -kPatchRadius; u <= kPatchRadius; ++u) m10 += u * centre[u];
  for (int v = 1; v <= kPatchRadius; ++v) {
    int row_sum = 0;  // sum over the row pair (+v, -v): contributes v * (I(+v) - I(-v)) to m01
    const int w = half_width[v];
    for (int u = -w; u <= w; ++u) {
      const int below = centre[u + v * step];
      const int above = centre[u - v * step];
      row_sum += below - above;
      m10 += u * (below + above);
    }
    m01 += v * row_sum;
  }
  return cv::fastAtan2(static_cast<float>(m01), static_cast<float>(m10));
}

Descriptor describe(const cv::Mat& blurred, int x, int y, float angle_deg, const std::vector<float>& pattern_x,
                    const std::vector<float>& pattern_y) {
  const float angle_rad = angle_deg * static_cast<float>(CV_PI / 180.0);
  const float c = std::cos(angle_rad);
  const float s = std::sin(angle_rad);
  const std::uint8_t* centre = blurred.ptr<std::uint8_t>(y) + x;
  const int step = static_cast<int>(blurred.step1());
  // Rotated sample offsets, rounded to the nearest pixel: adding 64.5 makes the value positive so
  // truncation is floor(v + 0.5); a plain loop the compiler vectorises.
  int offsets[512];
  for (int i = 0; i < 512; ++i) {
    const int rx = static_cast<int>(pattern_x[i] * c - pattern_y[i] * s + 64.5f) - 64;
    const int ry = static_cast<int>(pattern_x[i] * s + pattern_y[i] * c + 64.5f) - 64;
    offsets[i] = ry * step + rx;
  }
  Descriptor d{};
  for (int w = 0; w < 4; ++w) {
    std::uint64_t bits = 0;
    for (int b = 0; b < 64; ++b) {
      const int i = w * 64 + b;
      bits |= static_cast<std::uint64_t>(centre[offsets[2 * i]] < centre[offsets[2 * i + 1]]) << b;
    }
    d[w] = bits;
  }
  return d;
}

/// FAST corners of one level with an adaptive threshold per cell: one pass at iniThFAST over the
/// whole level, then cells left without a corner are searched again at minThFAST.
std::vector<cv::KeyPoint> detectCorners(const cv::Mat& level, int ini_threshold, int min_threshold) {
  std::vector<cv::KeyPoint> corners;
  const int x_min = kEdge - kFastMargin;
  const int y_min = kEdge - kFastMargin;
  const int x_max = level.cols - kEdge + kFastMargin;  // exclusive
  const int y_max = level.rows - kEdge + kFastMargin;
  if (x_max - x_min < 2 * kFastMargin + 1 || y_max - y_min < 2 * kFastMargin + 1) return corners;
  cv::FAST(level(cv::Range(y_min, y_max), cv::Range(x_min, x_max)), corners, ini_threshold, true);
  for (cv::KeyPoint& kp : corners) {
    kp.pt.x += static_cast<float>(x_min);
    kp.pt.y += static_cast<float>(y_min);
  }

  // Cells over the keypoint area [kEdge, size - kEdge).
  const int inner_w = x_max - x_min - 2 * kFastMargin;
  const int inner_h = y_max - y_min - 2 * kFastMargin;
  const int cols = std::max(1, inner_w / kCellSize);
  const int rows = std::max(1, inner_h / kCellSize);
  const int cell_w = (inner_w + cols - 1) / cols;
  const int cell_h = (inner_h + rows - 1) / rows;
  std::vector<char> occupied(static_cast<std::size_t>(cols) * rows, 0);
  for (const cv::KeyPoint& kp : corners) {
    const int c = std::min(cols - 1, (static_cast<int>(kp.pt.x) - kEdge) / cell_w);
    const int r = std::min(rows - 1, (static_cast<int>(kp.pt.y) - kEdge) / cell_h);
    occupied[static_cast<std::size_t>(r) * cols + c] = 1;
  }
  std::vector<cv::KeyPoint> cell_corners;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      if (occupied[static_cast<std::size_t>(r) * cols + c]) continue;
      const int x0 = kEdge + c * cell_w - kFastMargin;
      const int y0 = kEdge + r * cell_h - kFastMargin;
      const int x1 = std::min(x0 + cell_w + 2 * kFastMargin, x_max);
      const int y1 = std::min(y0 + cell_h + 2 * kFastMargin, y_max);
      if (x1 - x0 <= 2 * kFastMargin || y1 - y0 <= 2 * kFastMargin) continue;
      cell_corners.clear();
      cv::FAST(level(cv::Range(y0, y1), cv::Range(x0, x1)), cell_corners, min_threshold, true);
      for (cv::KeyPoint& kp : cell_corners) {
        kp.pt.x += static_cast<float>(x0);
        kp.pt.y += static_cast<float>(y0);
        corners.push_back(kp);
      }
    }
  }
  return corners;
}

}  // namespace

OrbExtractor::OrbExtractor(const OrbOptions& options) : options_(options) {
  if (options.num_features < 1 || options.num_features > 100000) {
    throw ConfigError("ORBextractor.nFeatures = " + std::to_string(options.num_features) +
                      ", expected an integer in [1, 100000]");
  }
  if (!(options.scale_factor > 1.0 && options.scale_factor <= 4.0)) {
    throw ConfigError("ORBextractor.scaleFactor = " + std::to_string(options.scale_factor) +
                      ", expected a value in (1, 4]");
  }
  if (options.num_levels < 1 || options.num_levels > 32) {
    throw ConfigError("ORBextractor.nLevels = " + std::to_string(options.num_levels) +
                      ", expected an integer in [1, 32]");
  }
  if (options.min_th_fast < 1 || options.ini_th_fast < options.min_th_fast || options.ini_th_fast > 255) {
    throw ConfigError("ORBextractor.iniThFAST = " + std::to_string(options.ini_th_fast) +
                      ", ORBextractor.minThFAST = " + std::to_string(options.min_th_fast) +
                      ", expected 1 <= minThFAST <= iniThFAST <= 255");
  }
  const int n = options.num_levels;
  scale_factors_.resize(n);
  level_sigma2_.resize(n);
  inv_level_sigma2_.resize(n);
  for (int l = 0; l < n; ++l) {
    scale_factors_[l] = static_cast<float>(std::pow(options.scale_factor, l));
    level_sigma2_[l] = scale_factors_[l] * scale_factors_[l];
    inv_level_sigma2_[l] = 1.0f / level_sigma2_[l];
  }
  // Features per level follow a geometric series in 1/scale: a level gets a share proportional to
  // its linear size, so that coarse levels (large scale) do not dominate.
  const double ratio = 1.0 / options.scale_factor;
  const double first = options.num_features * (1.0 - ratio) / (1.0 - std::pow(ratio, n));
  features_per_level_.resize(n);
  int assigned = 0;
  for (int l = 0; l + 1 < n; ++l) {
    features_per_level_[l] = static_cast<int>(std::lround(first * std::pow(ratio, l)));
    assigned += features_per_level_[l];
  }
  features_per_level_[n - 1] = std::max(0, options.num_features - assigned);

  circle_half_width_.resize(kPatchRadius + 1);
  for (int v = 0; v <= kPatchRadius; ++v) {
    circle_half_width_[v] = static_cast<int>(std::floor(std::sqrt(kPatchRadius * kPatchRadius - v * v)));
  }
  for (const cv::Point& p : makePattern()) {
    pattern_x_.push_back(static_cast<float>(p.x));
    pattern_y_.push_back(static_cast<float>(p.y));
  }
}

OrbFeatures OrbExtractor::extract(const cv::Mat& image_gray) const {
  if (image_gray.empty() || image_gray.type() != CV_8UC1) {
    throw InputError("OrbExtractor::extract: expected a non-empty CV_8UC1 image, got type " +
                     std::to_string(image_gray.type()));
  }
  OrbFeatures features;
  features.keypoints.reserve(options_.num_features);
  features.descriptors.reserve(options_.num_features);
  cv::Mat level = image_gray;
  cv::Mat blurred;
  for (int l = 0; l < options_.num_levels; ++l) {
    if (l > 0) {
      const cv::Size size(static_cast<int>(std::lround(image_gray.cols / scale_factors_[l])),
                          static_cast<int>(std::lround(image_gray.rows / scale_factors_[l])));
      if (size.width < 2 * kEdge + 1 || size.height < 2 * kEdge + 1) break;
      cv::Mat next;
      cv::resize(level, next, size, 0.0, 0.0, cv::INTER_LINEAR);
      level = next;
    }
    const std::vector<cv::KeyPoint> corners = detectCorners(level, options_.ini_th_fast, options_.min_th_fast);
    if (corners.empty() || features_per_level_[l] == 0) continue;
    const std::vector<int> kept =
        selectDistributed(corners, cv::Rect(kEdge, kEdge, level.cols - 2 * kEdge, level.rows - 2 * kEdge),
                          features_per_level_[l]);
    cv::GaussianBlur(level, blurred, cv::Size(7, 7), 2.0, 2.0, cv::BORDER_REFLECT_101);
    const float scale = scale_factors_[l];
    for (int index : kept) {
      const int x = static_cast<int>(std::lround(corners[index].pt.x));
      const int y = static_cast<int>(std::lround(corners[index].pt.y));
      Keypoint kp;
      kp.angle_deg = centroidAngleDeg(level, x, y, circle_half_width_);
      if (kp.angle_deg >= 360.0f) kp.angle_deg -= 360.0f;
      // Pixel centres: level pixel x covers level-0 [x s, (x + 1) s), centre (x + 0.5) s - 0.5.
      kp.x_px = (static_cast<float>(x) + 0.5f) * scale - 0.5f;
      kp.y_px = (static_cast<float>(y) + 0.5f) * scale - 0.5f;
      kp.response = corners[index].response;
      kp.octave = l;
      features.descriptors.push_back(describe(blurred, x, y, kp.angle_deg, pattern_x_, pattern_y_));
      features.keypoints.push_back(kp);
    }
  }
  return features;
}

}  // namespace ltlo::features
