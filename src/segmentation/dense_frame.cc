#include "ltlo/segmentation/dense_frame.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "ltlo/core/assert.h"

namespace ltlo::segmentation {

namespace {

inline bool validDepth(float z) { return z > 0.0f && z < std::numeric_limits<float>::infinity(); }

struct DepthGap {
  float at_zero, growth, max;
  float operator()(float z) const { return std::min(max, at_zero + growth * z * z); }
};

// Depth of each block x block of `fine` into `coarse` (pre-sized): the mean of the block's depths
// when they lie within the gap of each other, else the nearest one; `child` (when not null) gets
// the raster index inside the block of the pixel the depth (and later the label) came from.
void downsampleDepth(const cv::Mat& fine, int block, const DepthGap& gap, cv::Mat* coarse,
                     std::vector<std::uint8_t>* child) {
  for (int r = 0; r < coarse->rows; ++r) {
    float* out = coarse->ptr<float>(r);
    for (int c = 0; c < coarse->cols; ++c) {
      float z_min = std::numeric_limits<float>::max(), z_max = 0.0f, sum = 0.0f;
      int n = 0, first = -1, nearest = -1;
      for (int dv = 0; dv < block; ++dv) {
        const float* row = fine.ptr<float>(r * block + dv) + c * block;
        for (int du = 0; du < block; ++du) {
          const float z = row[du];
          if (!validDepth(z)) continue;
          const int index = dv * block + du;
          if (first < 0) first = index;
          if (z < z_min) {
            z_min = z;
            nearest = index;
          }
          z_max = std::max(z_max, z);
          sum += z;
          ++n;
        }
      }
      const bool smooth = n > 0 && z_max - z_min < gap(z_min);
      out[c] = n == 0 ? 0.0f : smooth ? sum / static_cast<float>(n) : z_min;
      if (child != nullptr) {
        (*child)[static_cast<std::size_t>(r) * coarse->cols + c] =
            static_cast<std::uint8_t>(n == 0 ? 0 : smooth ? first : nearest);
      }
    }
  }
}

// Central difference along one axis from the samples before (a) and after (b) the pixel (p);
// depth: only samples with depth count, one-sided where one side has none. This is the |grad D|
// of the weight w_D (Eq. 64): large across a depth discontinuity, which is what it detects.
inline float depthDerivative(float a, float p, float b) {
  const bool has_a = validDepth(a), has_b = validDepth(b);
  if (has_a && has_b) return 0.5f * (b - a);
  if (has_b) return b - p;
  if (has_a) return p - a;
  return 0.0f;
}

// The slope of the pixel's own surface along one axis: like depthDerivative, but a neighbour
// farther than the gap from p lies on another surface and does not count (one-sided where one
// neighbour does, 0 where neither does). This is the gradient of the depth residual's Jacobian
// (Eq. 62): across a discontinuity the bilinear residual of a sample on either side does not
// change with the warp, and a central difference across it (half the jump per pixel) would make
// the Gauss-Newton model far stiffer than the cost, so the steps would shrink only slowly.
inline float surfaceDerivative(float a, float p, float b, float gap_m) {
  const bool has_a = validDepth(a) && std::abs(p - a) < gap_m, has_b = validDepth(b) && std::abs(b - p) < gap_m;
  if (has_a && has_b) return 0.5f * (b - a);
  if (has_b) return b - p;
  if (has_a) return p - a;
  return 0.0f;
}

// Whether the 2 x 2 cell with top-left (r, c) lies on one surface: all four depths valid and
// within the gap of the nearest. A bilinear depth sample inside a cell that is not mixes two
// surfaces: it is no measurement of either.
inline bool smoothCell(const cv::Mat& depth_m, int r, int c, const DepthGap& gap) {
  if (r + 1 >= depth_m.rows || c + 1 >= depth_m.cols) return false;
  const float* top = depth_m.ptr<float>(r) + c;
  const float* bottom = depth_m.ptr<float>(r + 1) + c;
  const float z[4] = {top[0], top[1], bottom[0], bottom[1]};
  float z_min = std::numeric_limits<float>::max(), z_max = 0.0f;
  for (const float zk : z) {
    if (!validDepth(zk)) return false;
    z_min = std::min(z_min, zk);
    z_max = std::max(z_max, zk);
  }
  return z_max - z_min < gap(z_min);
}

// Gradients, lookup table and the per-pixel arrays of one level (everything but the labels).
void prepareLevel(const DenseFrameOptions& options, const DepthGap& gap, DenseLevel* level_out) {
  DenseLevel& level = *level_out;
  const int w = level.camera.width, h = level.camera.height;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  level.lookup.resize(n * kLookupChannels);
  level.x_m.clear();
  level.y_m.clear();
  level.z_m.clear();
  level.intensity_at.clear();
  level.weight_I.clear();
  level.weight_D.clear();
  level.pixel.clear();
  const float noise_I = static_cast<float>(options.lambda_intensity * options.sigma_intensity * options.sigma_intensity);
  const float lambda_D = static_cast<float>(options.lambda_depth);
  const float sigma_D = static_cast<float>(options.sigma_depth_m);
  const float inv_fx = 1.0f / level.camera.fx, inv_fy = 1.0f / level.camera.fy;
  for (int r = 0; r < h; ++r) {
    const float* I = level.intensity.ptr<float>(r);
    const float* I_up = level.intensity.ptr<float>(std::max(r - 1, 0));
    const float* I_down = level.intensity.ptr<float>(std::min(r + 1, h - 1));
    const float* D = level.depth_m.ptr<float>(r);
    const float* D_up = r > 0 ? level.depth_m.ptr<float>(r - 1) : nullptr;
    const float* D_down = r + 1 < h ? level.depth_m.ptr<float>(r + 1) : nullptr;
    const float v_scale = (r > 0 && r + 1 < h) ? 0.5f : 1.0f;
    for (int c = 0; c < w; ++c) {
      const int c0 = std::max(c - 1, 0), c1 = std::min(c + 1, w - 1);
      const float Iu = (I[c1] - I[c0]) * ((c > 0 && c + 1 < w) ? 0.5f : 1.0f);
      const float Iv = (I_down[c] - I_up[c]) * v_scale;
      const float z = D[c];
      const bool has_depth = validDepth(z);
      float Du = 0.0f, Dv = 0.0f, surface_Du = 0.0f, surface_Dv = 0.0f;
      if (has_depth) {
        const float left = c > 0 ? D[c - 1] : 0.0f, right = c + 1 < w ? D[c + 1] : 0.0f;
        const float up = D_up != nullptr ? D_up[c] : 0.0f, down = D_down != nullptr ? D_down[c] : 0.0f;
        Du = depthDerivative(left, z, right);
        Dv = depthDerivative(up, z, down);
        const float gap_m = gap(z);
        surface_Du = surfaceDerivative(left, z, right, gap_m);
        surface_Dv = surfaceDerivative(up, z, down, gap_m);
      }
      float* entry = &level.lookup[(static_cast<std::size_t>(r) * w + c) * kLookupChannels];
      entry[kLookupI] = I[c];
      entry[kLookupIu] = Iu;
      entry[kLookupIv] = Iv;
      entry[kLookupD] = has_depth ? z : 0.0f;
      entry[kLookupDu] = surface_Du;
      entry[kLookupDv] = surface_Dv;
      entry[kLookupValid] = has_depth ? 1.0f : 0.0f;
      entry[kLookupSmoothCell] = smoothCell(level.depth_m, r, c, gap) ? 1.0f : 0.0f;
      if (!has_depth) continue;
      const float sigma_z = sigma_D * z * z;
      level.x_m.push_back((static_cast<float>(c) - level.camera.cx) * inv_fx * z);
      level.y_m.push_back((static_cast<float>(r) - level.camera.cy) * inv_fy * z);
      level.z_m.push_back(z);
      level.intensity_at.push_back(I[c]);
      level.weight_I.push_back(1.0f / (noise_I + std::sqrt(Iu * Iu + Iv * Iv)));           // Eq. 64
      level.weight_D.push_back(1.0f / (lambda_D * sigma_z * sigma_z + std::sqrt(Du * Du + Dv * Dv)));  // Eq. 64
      level.pixel.push_back(r * w + c);
    }
  }
}

}  // namespace

DenseFrameOptions DenseFrameOptions::from(const SegmentationOptions& segmentation, const DenseOptions& dense) {
  DenseFrameOptions options;
  options.width = dense.width;
  options.height = dense.height;
  options.num_levels = dense.pyramid_levels;
  options.finest_solved_level = dense.finest_level;
  options.lambda_intensity = segmentation.noise_weight_intensity;
  options.sigma_intensity = segmentation.sigma_intensity;
  options.lambda_depth = segmentation.noise_weight_depth;
  options.sigma_depth_m = segmentation.sigma_depth_m;
  options.max_gap_m = segmentation.max_neighbour_gap_m;
  return options;
}

LevelCamera DenseFrame::levelCamera(const PinholeCamera& input_camera, int scale) {
  LTLO_ASSERT(scale >= 1 && input_camera.width() % scale == 0 && input_camera.height() % scale == 0,
              "the input " << input_camera.width() << "x" << input_camera.height() << " is not a multiple of "
                           << scale);
  LevelCamera camera;
  camera.width = input_camera.width() / scale;
  camera.height = input_camera.height() / scale;
  // A level pixel averages scale x scale input pixels: its centre is at input (s c + (s - 1) / 2).
  camera.fx = static_cast<float>(input_camera.fx() / scale);
  camera.fy = static_cast<float>(input_camera.fy() / scale);
  camera.cx = static_cast<float>((input_camera.cx() + 0.5) / scale - 0.5);
  camera.cy = static_cast<float>((input_camera.cy() + 0.5) / scale - 0.5);
  return camera;
}

void DenseFrame::build(const cv::Mat& color, const cv::Mat& depth_m, const PinholeCamera& input_camera,
                       const DenseFrameOptions& options) {
  LTLO_ASSERT(depth_m.type() == CV_32F, "depth type " << depth_m.type() << ", expected CV_32F");
  LTLO_ASSERT(color.type() == CV_8UC3 || color.type() == CV_8UC1, "colour type " << color.type());
  LTLO_ASSERT(color.size() == depth_m.size() && depth_m.cols == input_camera.width() &&
                  depth_m.rows == input_camera.height(),
              "colour " << color.cols << "x" << color.rows << ", depth " << depth_m.cols << "x" << depth_m.rows
                        << ", camera " << input_camera.width() << "x" << input_camera.height());
  LTLO_ASSERT(options.num_levels >= 1, "num_levels = " << options.num_levels);
  scale_ = input_camera.width() / options.width;
  LTLO_ASSERT(scale_ >= 1 && scale_ * options.width == input_camera.width() &&
                  scale_ * options.height == input_camera.height(),
              "input " << input_camera.width() << "x" << input_camera.height() << " is not an integer multiple of "
                       << options.width << "x" << options.height);
  const DepthGap gap{static_cast<float>(options.gap_at_zero_m), static_cast<float>(options.gap_growth_per_m),
                     static_cast<float>(options.max_gap_m)};
  levels_.resize(static_cast<std::size_t>(options.num_levels));
  num_clusters_ = 0;
  for (int l = 0; l < options.num_levels; ++l) {
    DenseLevel& level = levels_[static_cast<std::size_t>(l)];
    level.camera = levelCamera(input_camera, scale_ << l);
    level.intensity.create(level.camera.height, level.camera.width, CV_32F);
    level.depth_m.create(level.camera.height, level.camera.width, CV_32F);
    level.child.resize(static_cast<std::size_t>(level.camera.width) * level.camera.height);
    if (l == 0) {
      if (color.channels() == 3) {
        cv::cvtColor(color, gray_, cv::COLOR_BGR2GRAY);
      } else {
        gray_ = color;
      }
      if (scale_ == 1) {
        gray_.convertTo(level.intensity, CV_32F, 1.0 / 255.0);
      } else {
        gray_.convertTo(gray_float_, CV_32F, 1.0 / 255.0);
        cv::resize(gray_float_, level.intensity, level.intensity.size(), 0.0, 0.0, cv::INTER_AREA);
      }
      downsampleDepth(depth_m, scale_, gap, &level.depth_m, nullptr);
    } else {
      const DenseLevel& finer = levels_[static_cast<std::size_t>(l - 1)];
      cv::resize(finer.intensity, level.intensity, level.intensity.size(), 0.0, 0.0, cv::INTER_AREA);
      downsampleDepth(finer.depth_m, 2, gap, &level.depth_m, &level.child);
    }
    if (l >= options.finest_solved_level) {
      prepareLevel(options, gap, &level);
    } else {
      level.lookup.clear();
      level.pixel.clear();
    }
  }
}

void DenseFrame::setLabels(const cv::Mat& labels, int num_clusters) {
  LTLO_ASSERT(!levels_.empty(), "setLabels before build");
  LTLO_ASSERT(labels.type() == CV_8U && labels.cols == levels_[0].camera.width && labels.rows == levels_[0].camera.height,
              "labels " << labels.cols << "x" << labels.rows << " of type " << labels.type() << " for a "
                        << levels_[0].camera.width << "x" << levels_[0].camera.height << " level 0");
  num_clusters_ = num_clusters;
  labels.copyTo(levels_[0].labels);
  for (std::size_t l = 1; l < levels_.size(); ++l) {
    DenseLevel& level = levels_[l];
    const cv::Mat& finer = levels_[l - 1].labels;
    level.labels.create(level.camera.height, level.camera.width, CV_8U);
    for (int r = 0; r < level.camera.height; ++r) {
      std::uint8_t* out = level.labels.ptr<std::uint8_t>(r);
      const float* depth = level.depth_m.ptr<float>(r);
      for (int c = 0; c < level.camera.width; ++c) {
        if (!validDepth(depth[c])) {
          out[c] = static_cast<std::uint8_t>(num_clusters);
          continue;
        }
        const int index = level.child[static_cast<std::size_t>(r) * level.camera.width + c];
        out[c] = finer.ptr<std::uint8_t>(2 * r + index / 2)[2 * c + index % 2];
      }
    }
  }
  for (DenseLevel& level : levels_) {
    level.label.resize(level.pixel.size());
    const std::uint8_t* data = level.labels.ptr<std::uint8_t>(0);
    for (std::size_t i = 0; i < level.pixel.size(); ++i) level.label[i] = data[level.pixel[i]];
  }
}

}  // namespace ltlo::segmentation
