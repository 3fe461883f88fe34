#include "measurement.h"

#include <cmath>
#include <functional>
#include <opencv2/imgproc.hpp>

#include "ltlo/core/assert.h"

namespace ltlo::recon {

PinholeCamera fusionCamera(const PinholeCamera& camera, int downsample) {
  const double s = downsample;
  return PinholeCamera(camera.fx() / s, camera.fy() / s, (camera.cx() + 0.5) / s - 0.5,
                       (camera.cy() + 0.5) / s - 0.5, camera.width() / downsample,
                       camera.height() / downsample);
}

namespace {

// Two depths of one surface differ by less than this: 5 % of the depth (a surface seen at up to
// ~87 deg across a pixel or two) plus three noise sigmas.
inline float jumpToleranceM(float noise_at_1m, float depth_m) {
  return 0.05f * depth_m + 3.0f * noise_at_1m * depth_m * depth_m;
}

void resize(int width, int height, Measurement* m) {
  const std::size_t n = static_cast<std::size_t>(width) * height;
  if (m->width != width || m->height != height) {
    // Per-pixel constants: the ray through the pixel centre (z = 1) and the radial weight alpha
    // = exp(-gamma^2 / (2 sigma^2)), gamma the distance from the principal point over the
    // centre-to-corner distance, sigma = 0.6 (Keller et al. 2013).
    m->ray_c.resize(n);
    m->alpha.resize(n);
  }
  m->width = width;
  m->height = height;
  m->state.assign(n, PixelState::kInvalid);
  m->depth_m.assign(n, 0.0f);
  m->smoothed_depth_m.assign(n, 0.0f);
  m->scratch_m.assign(n, 0.0f);
  m->point_c.resize(n);
  m->normal_c.resize(n);
  m->colour_rgb.resize(n);
  m->radius_m.resize(n);
  m->dynamic.assign(n, 0);
  m->num_geometry = 0;
  m->num_fusable = 0;
}

void fillPixelConstants(const PinholeCamera& fusion_camera, Measurement* m) {
  const float fx = static_cast<float>(fusion_camera.fx());
  const float fy = static_cast<float>(fusion_camera.fy());
  const float cx = static_cast<float>(fusion_camera.cx());
  const float cy = static_cast<float>(fusion_camera.cy());
  const float inv_corner2 = 1.0f / (cx * cx + cy * cy);
  const float inv_two_sigma2 = 1.0f / (2.0f * 0.6f * 0.6f);
  for (int j = 0; j < m->height; ++j) {
    for (int i = 0; i < m->width; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * m->width + i;
      m->ray_c[k] = Eigen::Vector3f((i - cx) / fx, (j - cy) / fy, 1.0f);
      const float du = i - cx, dv = j - cy;
      m->alpha[k] = std::exp(-(du * du + dv * dv) * inv_corner2 * inv_two_sigma2);
    }
  }
}

// Blocks touched by the dynamic mask grown by options.mask_dilation_px input pixels.
void markDynamicBlocks(const cv::Mat& mask, const ReconOptions& options, Measurement* m) {
  if (mask.empty() || cv::countNonZero(mask) == 0) return;  // most frames of most sequences
  cv::Mat grown = mask;
  if (options.mask_dilation_px > 0) {
    const int k = 2 * options.mask_dilation_px + 1;
    cv::dilate(mask, grown, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k)));
  }
  const int s = options.downsample;
  for (int j = 0; j < m->height; ++j) {
    uint8_t* out = &m->dynamic[static_cast<std::size_t>(j) * m->width];
    for (int dv = 0; dv < s; ++dv) {
      const uint8_t* row = grown.ptr<uint8_t>(j * s + dv);
      for (int i = 0; i < m->width; ++i) {
        uint8_t any = 0;
        for (int du = 0; du < s; ++du) any |= row[i * s + du];
        out[i] |= any != 0 ? 1 : 0;
      }
    }
  }
}

// Block means of rows [j_begin, j_end) of the fusion grid: depth where every input pixel of the
// block lies in [min, max] and on one surface, and colour (RGB).
void blockMeans(const FusionFrame& frame, const ReconOptions& options, int j_begin, int j_end,
                Measurement* m) {
  const int s = options.downsample;
  const float min_depth = static_cast<float>(options.min_depth_m);
  const float max_depth = static_cast<float>(options.max_depth_m);
  const float noise = static_cast<float>(options.depth_noise_m);
  const float inv_count = 1.0f / static_cast<float>(s * s);
  const bool with_colour = !frame.colour_bgr.empty();
  for (int j = j_begin; j < j_end; ++j) {
    for (int i = 0; i < m->width; ++i) {
      float z_sum = 0.0f, z_min = max_depth, z_max = 0.0f;
      float b = 0.0f, g = 0.0f, r = 0.0f;
      bool valid = true;
      for (int dv = 0; dv < s; ++dv) {
        const float* z_row = frame.depth_m.ptr<float>(j * s + dv) + i * s;
        for (int du = 0; du < s; ++du) {
          const float z = z_row[du];
          valid &= z >= min_depth && z <= max_depth;
          z_sum += z;
          z_min = std::min(z_min, z);
          z_max = std::max(z_max, z);
        }
        if (!with_colour) continue;
        const uint8_t* c_row = frame.colour_bgr.ptr<uint8_t>(j * s + dv) + 3 * i * s;
        for (int du = 0; du < s; ++du) {
          b += c_row[3 * du];
          g += c_row[3 * du + 1];
          r += c_row[3 * du + 2];
        }
      }
      if (!valid || z_max - z_min > jumpToleranceM(noise, z_min)) continue;
      const std::size_t k = static_cast<std::size_t>(j) * m->width + i;
      const float z = z_sum * inv_count;
      m->depth_m[k] = z;
      m->point_c[k] = m->ray_c[k] * z;
      m->colour_rgb[k] = Eigen::Vector3f(r, g, b) * inv_count;
    }
  }
}

// The edge-aware 5-tap mean at one element: the mean of the non-zero neighbours within the jump
// tolerance of the centre (offsets -2..2 times `step`, those with valid[d + 2]); 0 stays 0.
inline float smoothedAt(const float* in, std::size_t k, std::ptrdiff_t step, const bool valid[5],
                        float noise) {
  const float z = in[k];
  const float tol = jumpToleranceM(noise, z);
  float sum = z;
  float count = 1.0f;
  const float* centre = in + k;
  auto add = [&](bool inside, std::ptrdiff_t offset) {
    const float zn = inside ? centre[offset] : 0.0f;
    const bool same = zn != 0.0f && std::abs(zn - z) <= tol;
    sum += same ? zn : 0.0f;
    count += same ? 1.0f : 0.0f;
  };
  add(valid[0], -2 * step);
  add(valid[1], -step);
  add(valid[3], step);
  add(valid[4], 2 * step);
  return z == 0.0f ? 0.0f : sum / count;
}

// Rows [j_begin, j_end) smoothed along the row (neighbours i - 2 .. i + 2).
void smoothAlongRows(const float* in, float* out, int width, int j_begin, int j_end, float noise) {
  const bool inside[5] = {true, true, true, true, true};
  for (int j = j_begin; j < j_end; ++j) {
    const std::size_t row = static_cast<std::size_t>(j) * width;
    for (int i = 0; i < width; ++i) {
      if (i >= 2 && i + 2 < width) {
        out[row + i] = smoothedAt(in, row + i, 1, inside, noise);
      } else {
        const bool valid[5] = {i >= 2, i >= 1, true, i + 1 < width, i + 2 < width};
        out[row + i] = smoothedAt(in, row + i, 1, valid, noise);
      }
    }
  }
}

// Rows [j_begin, j_end) smoothed along the columns (neighbours j - 2 .. j + 2).
void smoothAlongColumns(const float* in, float* out, int width, int height, int j_begin, int j_end,
                        float noise) {
  for (int j = j_begin; j < j_end; ++j) {
    const bool valid[5] = {j >= 2, j >= 1, true, j + 1 < height, j + 2 < height};
    const std::size_t row = static_cast<std::size_t>(j) * width;
    for (int i = 0; i < width; ++i) out[row + i] = smoothedAt(in, row + i, width, valid, noise);
  }
}

// Rows [0, n) split over `pool`'s threads, or all on the calling thread without a pool.
void forRows(WorkerPool* pool, int n, const std::function<void(int, int, int)>& f) {
  if (pool != nullptr) {
    pool->parallelFor(n, f);
  } else if (n > 0) {
    f(0, n, 0);
  }
}

}  // namespace

void computeMeasurement(const FusionFrame& frame, const PinholeCamera& camera,
                        const PinholeCamera& fusion_camera, const ReconOptions& options,
                        WorkerPool* pool, Measurement* m) {
  LTLO_ASSERT(frame.depth_m.type() == CV_32F && frame.depth_m.cols == camera.width() &&
                  frame.depth_m.rows == camera.height(),
              "depth image " << frame.depth_m.cols << "x" << frame.depth_m.rows << " vs camera "
                             << camera.width() << "x" << camera.height());
  LTLO_ASSERT(frame.colour_bgr.empty() || (frame.colour_bgr.type() == CV_8UC3 &&
                                            frame.colour_bgr.size() == frame.depth_m.size()),
              "colour image type or size");
  LTLO_ASSERT(frame.dynamic_mask.empty() || (frame.dynamic_mask.type() == CV_8UC1 &&
                                             frame.dynamic_mask.size() == frame.depth_m.size()),
              "dynamic mask type or size");
  const int width = fusion_camera.width();
  const int height = fusion_camera.height();
  const bool new_size = m->width != width || m->height != height;
  resize(width, height, m);
  if (new_size) fillPixelConstants(fusion_camera, m);
  markDynamicBlocks(frame.dynamic_mask, options, m);
  forRows(pool, height,
          [&](int begin, int end, int) { blockMeans(frame, options, begin, end, m); });

  // Normals from an edge-aware 5 x 5 box smoothing of the depth (neighbours on the same surface
  // only), by central differences two pixels apart: raw differences of neighbouring fusion pixels
  // are dominated by depth noise beyond 2 m (about 20 deg at 3 m on a VGA structured-light sensor).
  const float noise = static_cast<float>(options.depth_noise_m);
  forRows(pool, height, [&](int begin, int end, int) {
    smoothAlongRows(m->depth_m.data(), m->scratch_m.data(), width, begin, end, noise);
  });
  forRows(pool, height, [&](int begin, int end, int) {
    smoothAlongColumns(m->scratch_m.data(), m->smoothed_depth_m.data(), width, height, begin, end,
                       noise);
  });
  const std::vector<float>& depth = m->depth_m;
  const std::vector<float>& smooth = m->smoothed_depth_m;
  const float fx = static_cast<float>(fusion_camera.fx());
  const float min_cos_view = static_cast<float>(std::cos(options.max_view_angle_deg * M_PI / 180));
  // Same-surface neighbours at +-step along one axis, step 2 (less noise) or else 1 (thin
  // structures such as table legs are only a few fusion pixels wide).
  auto sameSurface = [&](std::size_t a, std::size_t b, float z, float tol) {
    return smooth[a] != 0.0f && smooth[b] != 0.0f && std::abs(smooth[a] - z) <= tol &&
           std::abs(smooth[b] - z) <= tol;
  };
  const int parts = pool != nullptr ? pool->parts() : 1;
  std::vector<int> num_geometry(parts, 0), num_fusable(parts, 0);
  forRows(pool, height - 2, [&](int row_begin, int row_end, int part) {
    for (int j = row_begin + 1; j < row_end + 1; ++j) {
      for (int i = 1; i + 1 < width; ++i) {
        const std::size_t k = static_cast<std::size_t>(j) * width + i;
        const float z = depth[k];
        if (z == 0.0f) continue;
        int step_u = 0, step_v = 0;
        for (int step : {2, 1}) {
          const float tol = step * jumpToleranceM(noise, z);
          if (step_u == 0 && i - step >= 0 && i + step < width &&
              sameSurface(k - step, k + step, z, tol)) {
            step_u = step;
          }
          const std::size_t dk = static_cast<std::size_t>(step) * width;
          if (step_v == 0 && j - step >= 0 && j + step < height &&
              sameSurface(k - dk, k + dk, z, tol)) {
            step_v = step;
          }
        }
        if (step_u == 0 || step_v == 0) continue;
        const std::size_t dk = static_cast<std::size_t>(step_v) * width;
        Eigen::Vector3f n =
            (m->ray_c[k + step_u] * smooth[k + step_u] - m->ray_c[k - step_u] * smooth[k - step_u])
                .cross(m->ray_c[k + dk] * smooth[k + dk] - m->ray_c[k - dk] * smooth[k - dk]);
        const float norm = n.norm();
        if (!(norm > 0.0f)) continue;
        n /= norm;
        const Eigen::Vector3f& p = m->point_c[k];
        float cos_view = -n.dot(p) / p.norm();
        if (cos_view < 0.0f) {
          n = -n;
          cos_view = -cos_view;
        }
        m->normal_c[k] = n;
        m->state[k] = PixelState::kGeometry;
        ++num_geometry[part];
        if (cos_view < min_cos_view || m->dynamic[k] != 0) continue;
        m->state[k] = PixelState::kFusable;
        ++num_fusable[part];
        // Disc through the corners of the pixel's footprint, stretched by the viewing angle.
        m->radius_m[k] = 0.70710678f * (z / fx) / cos_view;
      }
    }
  });
  for (int part = 0; part < parts; ++part) {
    m->num_geometry += num_geometry[part];
    m->num_fusable += num_fusable[part];
  }
}

}  // namespace ltlo::recon
