#include "measurement.h"

#include <cmath>
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
inline float jumpToleranceM(const ReconOptions& options, float depth_m) {
  return 0.05f * depth_m + 3.0f * static_cast<float>(options.depth_noise_m) * depth_m * depth_m;
}

void resize(int width, int height, Measurement* m) {
  const std::size_t n = static_cast<std::size_t>(width) * height;
  m->width = width;
  m->height = height;
  m->state.assign(n, PixelState::kInvalid);
  m->depth_m.assign(n, 0.0f);
  m->point_c.resize(n);
  m->normal_c.resize(n);
  m->colour_rgb.resize(n);
  m->radius_m.resize(n);
  m->alpha.resize(n);
  m->dynamic.assign(n, 0);
  m->num_geometry = 0;
  m->num_fusable = 0;
}

// Blocks touched by the dynamic mask grown by options.mask_dilation_px input pixels.
void markDynamicBlocks(const cv::Mat& mask, const ReconOptions& options, Measurement* m) {
  if (mask.empty()) return;
  cv::Mat grown = mask;
  if (options.mask_dilation_px > 0) {
    const int k = 2 * options.mask_dilation_px + 1;
    cv::dilate(mask, grown, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k)));
  }
  const int s = options.downsample;
  for (int v = 0; v < m->height * s; ++v) {
    const uint8_t* row = grown.ptr<uint8_t>(v);
    uint8_t* out = &m->dynamic[static_cast<std::size_t>(v / s) * m->width];
    for (int u = 0; u < m->width * s; ++u) {
      if (row[u] != 0) out[u / s] = 1;
    }
  }
}

// Mean of the depths within +-2 pixels along one axis that lie on the same surface as the centre
// (within the jump tolerance); 0 stays 0.
// Element (i, j) is in[j * stride_j + i * stride_i]; smoothing runs along i, for j in
// [j_begin, j_end).
void smoothAxis(const std::vector<float>& in, int stride_i, int stride_j, int length_i, int j_begin,
                int j_end, const ReconOptions& options, std::vector<float>* out) {
  for (int j = j_begin; j < j_end; ++j) {
    for (int i = 0; i < length_i; ++i) {
      const std::size_t k =
          static_cast<std::size_t>(j) * stride_j + static_cast<std::size_t>(i) * stride_i;
      const float z = in[k];
      if (z == 0.0f) {
        (*out)[k] = 0.0f;
        continue;
      }
      const float tol = jumpToleranceM(options, z);
      float sum = z;
      int count = 1;
      for (int d = -2; d <= 2; ++d) {
        if (d == 0 || i + d < 0 || i + d >= length_i) continue;
        const float zn = in[k + d * stride_i];
        if (zn != 0.0f && std::abs(zn - z) <= tol) {
          sum += zn;
          ++count;
        }
      }
      (*out)[k] = sum / count;
    }
  }
}

void smoothDepth(const std::vector<float>& depth, int width, int height,
                 const ReconOptions& options, WorkerPool* pool, std::vector<float>* smoothed,
                 std::vector<float>* scratch) {
  scratch->resize(depth.size());
  smoothed->resize(depth.size());
  pool->parallelFor(height, [&](int begin, int end, int) {  // along rows
    smoothAxis(depth, 1, width, width, begin, end, options, scratch);
  });
  pool->parallelFor(width, [&](int begin, int end, int) {  // along columns
    smoothAxis(*scratch, width, 1, height, begin, end, options, smoothed);
  });
}

}  // namespace

void computeMeasurement(const FusionFrame& frame, const PinholeCamera& camera,
                        const PinholeCamera& fusion_camera, const ReconOptions& options,
                        WorkerPool* pool, Measurement* m) {
  LTLO_ASSERT(frame.depth_m.type() == CV_32F && frame.depth_m.cols == camera.width() &&
                  frame.depth_m.rows == camera.height(),
              "depth image " << frame.depth_m.cols << "x" << frame.depth_m.rows << " vs camera "
                             << camera.width() << "x" << camera.height());
  LTLO_ASSERT(frame.colour_bgr.type() == CV_8UC3 && frame.colour_bgr.size() == frame.depth_m.size(),
              "colour image type or size");
  LTLO_ASSERT(frame.dynamic_mask.empty() || (frame.dynamic_mask.type() == CV_8UC1 &&
                                             frame.dynamic_mask.size() == frame.depth_m.size()),
              "dynamic mask type or size");
  const int s = options.downsample;
  const int width = fusion_camera.width();
  const int height = fusion_camera.height();
  resize(width, height, m);
  markDynamicBlocks(frame.dynamic_mask, options, m);

  const float min_depth = static_cast<float>(options.min_depth_m);
  const float max_depth = static_cast<float>(options.max_depth_m);
  const float inv_count = 1.0f / static_cast<float>(s * s);
  const float fx = static_cast<float>(fusion_camera.fx());
  const float fy = static_cast<float>(fusion_camera.fy());
  const float cx = static_cast<float>(fusion_camera.cx());
  const float cy = static_cast<float>(fusion_camera.cy());

  // Block averages -> vertices (kGeometry marks "has a vertex" until the normals are known).
  std::vector<float>& depth = m->depth_m;
  pool->parallelFor(height, [&](int j_begin, int j_end, int) {
    for (int j = j_begin; j < j_end; ++j) {
      for (int i = 0; i < width; ++i) {
        float z_sum = 0.0f, z_min = max_depth, z_max = 0.0f;
        Eigen::Vector3f bgr_sum = Eigen::Vector3f::Zero();
        bool valid = true;
        for (int dv = 0; dv < s && valid; ++dv) {
          const float* z_row = frame.depth_m.ptr<float>(j * s + dv) + i * s;
          const cv::Vec3b* c_row = frame.colour_bgr.ptr<cv::Vec3b>(j * s + dv) + i * s;
          for (int du = 0; du < s; ++du) {
            const float z = z_row[du];
            if (!(z >= min_depth && z <= max_depth)) {
              valid = false;
              break;
            }
            z_sum += z;
            z_min = std::min(z_min, z);
            z_max = std::max(z_max, z);
            bgr_sum += Eigen::Vector3f(c_row[du][0], c_row[du][1], c_row[du][2]);
          }
        }
        if (!valid || z_max - z_min > jumpToleranceM(options, z_min)) continue;
        const std::size_t k = static_cast<std::size_t>(j) * width + i;
        const float z = z_sum * inv_count;
        depth[k] = z;
        m->point_c[k] = Eigen::Vector3f((i - cx) / fx * z, (j - cy) / fy * z, z);
        m->colour_rgb[k] = Eigen::Vector3f(bgr_sum.z(), bgr_sum.y(), bgr_sum.x()) * inv_count;
      }
    }
  });

  // Normals from an edge-aware 5 x 5 box smoothing of the depth (neighbours on the same surface
  // only), by central differences two pixels apart: raw differences of neighbouring fusion pixels
  // are dominated by depth noise beyond 2 m (about 20 deg at 3 m on a VGA structured-light sensor).
  smoothDepth(depth, width, height, options, pool, &m->smoothed_depth_m, &m->scratch_m);
  const std::vector<float>& smooth = m->smoothed_depth_m;
  auto smoothPoint = [&](std::size_t k, int i, int j) {
    const float z = smooth[k];
    return Eigen::Vector3f((i - cx) / fx * z, (j - cy) / fy * z, z);
  };
  const float min_cos_view = static_cast<float>(std::cos(options.max_view_angle_deg * M_PI / 180));
  const float inv_corner2 = 1.0f / (cx * cx + cy * cy);
  const float inv_two_sigma2 = 1.0f / (2.0f * 0.6f * 0.6f);  // Keller et al. 2013, sigma = 0.6
  // Same-surface neighbours at +-step along one axis, step 2 (less noise) or else 1 (thin
  // structures such as table legs are only a few fusion pixels wide).
  auto sameSurface = [&](std::size_t a, std::size_t b, float z, float tol) {
    return smooth[a] != 0.0f && smooth[b] != 0.0f && std::abs(smooth[a] - z) <= tol &&
           std::abs(smooth[b] - z) <= tol;
  };
  std::vector<int> num_geometry(pool->parts(), 0), num_fusable(pool->parts(), 0);
  pool->parallelFor(height - 2, [&](int row_begin, int row_end, int part) {
    for (int j = row_begin + 1; j < row_end + 1; ++j) {
      for (int i = 1; i + 1 < width; ++i) {
        const std::size_t k = static_cast<std::size_t>(j) * width + i;
        const float z = depth[k];
        if (z == 0.0f) continue;
        int step_u = 0, step_v = 0;
        for (int step : {2, 1}) {
          const float tol = step * jumpToleranceM(options, z);
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
            (smoothPoint(k + step_u, i + step_u, j) - smoothPoint(k - step_u, i - step_u, j))
                .cross(smoothPoint(k + dk, i, j + step_v) - smoothPoint(k - dk, i, j - step_v));
        const float norm = n.norm();
        if (!(norm > 0.0f)) continue;
        n /= norm;
        const Eigen::Vector3f& p = m->point_c[k];
        const float range = p.norm();
        float cos_view = -n.dot(p) / range;
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
        const float du = i - cx, dv = j - cy;
        m->alpha[k] = std::exp(-(du * du + dv * dv) * inv_corner2 * inv_two_sigma2);
      }
    }
  });
  for (int part = 0; part < pool->parts(); ++part) {
    m->num_geometry += num_geometry[part];
    m->num_fusable += num_fusable[part];
  }
}

}  // namespace ltlo::recon
