#include "dense_kernels.h"

#include <algorithm>
#include <cmath>

namespace ltlo::segmentation::detail {

namespace {

/// Points closer than this to the previous camera are not warped (behind it or degenerate), m.
constexpr float kMinWarpDepth_m = 0.05f;
/// A bilinear depth sample counts only when all four taps have depth.
constexpr float kAllTapsValid = 0.999f;
/// Intensities at or beyond these are taken as clipped by the sensor (8-bit 5 and 250 of 255, or a
/// pyramid pixel averaging clipped ones): no evidence for the brightness fit.
constexpr float kDarkestUnclipped = 5.0f / 255.0f;
constexpr float kBrightestUnclipped = 250.0f / 255.0f;

inline float unclipped(float I_current, float I_previous) {
  return I_current > kDarkestUnclipped && I_current < kBrightestUnclipped && I_previous > kDarkestUnclipped &&
                 I_previous < kBrightestUnclipped
             ? 1.0f
             : 0.0f;
}

/// The current pixel's point p (camera frame) in the previous camera and its projection there
/// (Eq. 63); false when it falls behind the camera or outside the bilinear domain.
struct Warped {
  float X, Y, Z, inv_Z, u, v;
};
inline bool warpPoint(const Warp& warp, const LevelCamera& camera, float x, float y, float z, Warped* out) {
  const float* R = warp.R;
  out->X = R[0] * x + R[1] * y + R[2] * z + warp.t[0];
  out->Y = R[3] * x + R[4] * y + R[5] * z + warp.t[1];
  out->Z = R[6] * x + R[7] * y + R[8] * z + warp.t[2];
  if (!(out->Z > kMinWarpDepth_m)) return false;
  out->inv_Z = 1.0f / out->Z;
  out->u = camera.fx * out->X * out->inv_Z + camera.cx;
  out->v = camera.fy * out->Y * out->inv_Z + camera.cy;
  return out->u >= 0.0f && out->v >= 0.0f && out->u < static_cast<float>(camera.width - 1) &&
         out->v < static_cast<float>(camera.height - 1);
}

/// Bilinear lookup of all channels at (u, v) (inside [0, w-1) x [0, h-1)).
inline void bilinear(const float* lookup, int width, float u, float v, float out[kLookupChannels]) {
  const int c = static_cast<int>(u), r = static_cast<int>(v);
  const float fu = u - static_cast<float>(c), fv = v - static_cast<float>(r);
  const float w00 = (1.0f - fu) * (1.0f - fv), w01 = fu * (1.0f - fv), w10 = (1.0f - fu) * fv, w11 = fu * fv;
  const float* p00 = lookup + (static_cast<std::size_t>(r) * width + c) * kLookupChannels;
  const float* p01 = p00 + kLookupChannels;
  const float* p10 = p00 + static_cast<std::size_t>(width) * kLookupChannels;
  const float* p11 = p10 + kLookupChannels;
  for (int k = 0; k < kLookupChannels; ++k) out[k] = w00 * p00[k] + w01 * p01[k] + w10 * p10[k] + w11 * p11[k];
}

/// Whether the cell holding (u, v) lies on one surface (kLookupSmoothCell of its top-left pixel).
inline bool smoothCellAt(const float* lookup, int width, float u, float v) {
  const std::size_t cell = static_cast<std::size_t>(static_cast<int>(v)) * width + static_cast<int>(u);
  return lookup[cell * kLookupChannels + kLookupSmoothCell] > 0.5f;
}

/// Cauchy penalty F(s) = c^2/2 log(1 + (s/c)^2) (Eq. 27 / 64) and its IRLS weight F'(s)/s.
inline float cauchy(float s, float inv_c2, float half_c2) { return half_c2 * std::log1p(s * s * inv_c2); }
inline float cauchyWeight(float s, float inv_c2) { return 1.0f / (1.0f + s * s * inv_c2); }

/// Jacobian row `row` (into the columns J[0..5]) of a residual whose gradient w.r.t. the warped
/// point is g (previous camera frame): d/d eps of R (Exp(eps) p) = R [-[p]x, I], so the row is
/// [p x h, h] with h = R^T g.
inline void writeRow(const Warp& warp, float x, float y, float z, float gx, float gy, float gz, std::size_t row,
                     float* const J[6]) {
  const float* R = warp.R;
  const float hx = R[0] * gx + R[3] * gy + R[6] * gz;
  const float hy = R[1] * gx + R[4] * gy + R[7] * gz;
  const float hz = R[2] * gx + R[5] * gy + R[8] * gz;
  J[0][row] = y * hz - z * hy;
  J[1][row] = z * hx - x * hz;
  J[2][row] = x * hy - y * hx;
  J[3][row] = hx;
  J[4][row] = hy;
  J[5][row] = hz;
}

constexpr int kLanes = 8;
constexpr int kAccumulators = 27;  // 21 of the upper triangle of H, 6 of b

/// H and b from the rows: per lane accumulators, so the inner loops vectorise without
/// reassociating a float sum.
void accumulateRows(const RowScratch& rows, std::size_t num_rows, ImageNormalEquations* out) {
  alignas(32) float acc[kAccumulators][kLanes] = {};
  const float* J[6] = {rows.J[0].data(), rows.J[1].data(), rows.J[2].data(),
                       rows.J[3].data(), rows.J[4].data(), rows.J[5].data()};
  const float* r = rows.r.data();
  const float* w = rows.w.data();
  std::size_t i = 0;
  for (; i + kLanes <= num_rows; i += kLanes) {
    float j[6][kLanes], wj[6][kLanes];
    for (int a = 0; a < 6; ++a) {
      for (int l = 0; l < kLanes; ++l) {
        j[a][l] = J[a][i + l];
        wj[a][l] = w[i + l] * J[a][i + l];
      }
    }
    int m = 0;
    for (int a = 0; a < 6; ++a) {
      for (int c = a; c < 6; ++c, ++m) {
        for (int l = 0; l < kLanes; ++l) acc[m][l] += wj[a][l] * j[c][l];
      }
    }
    for (int a = 0; a < 6; ++a) {
      for (int l = 0; l < kLanes; ++l) acc[21 + a][l] += wj[a][l] * r[i + l];
    }
  }
  for (; i < num_rows; ++i) {
    int m = 0;
    for (int a = 0; a < 6; ++a) {
      const float wja = w[i] * J[a][i];
      for (int c = a; c < 6; ++c, ++m) acc[m][0] += wja * J[c][i];
      acc[21 + a][0] += wja * r[i];
    }
  }
  double total[kAccumulators];
  for (int m = 0; m < kAccumulators; ++m) {
    double sum = 0.0;
    for (int l = 0; l < kLanes; ++l) sum += acc[m][l];
    total[m] = sum;
  }
  int m = 0;
  for (int a = 0; a < 6; ++a) {
    for (int c = a; c < 6; ++c, ++m) {
      out->H(a, c) += total[m];
      if (c != a) out->H(c, a) += total[m];
    }
    out->b(a) += total[21 + a];
  }
}

/// The brightness fit's block statistics from the gathered pixels [0, m) (scores, samples
/// s[kLookupI], current intensities I, blocks): a scatter over the blocks, one pass.
void accumulateBrightnessBlocks(const RowScratch& rows, std::size_t m, BrightnessBlocks* out) {
  const float* gamma = rows.gamma.data();
  const float* I = rows.I.data();
  const float* s = rows.s[kLookupI].data();
  const float* one_surface = rows.s[kLookupValid].data();
  const int* block = rows.block.data();
  double* w = out->w.data();
  double* x = out->x.data();
  double* sum_s = out->s.data();
  for (std::size_t j = 0; j < m; ++j) {
    const float wu = gamma[j] * one_surface[j] * unclipped(I[j], s[j]);
    const std::size_t b = static_cast<std::size_t>(block[j]);
    w[b] += wu;
    x[b] += wu * (I[j] - 0.5f);
    sum_s[b] += wu * s[j];
  }
}

/// The rows of the gathered pixels [0, m) (see accumulateImageTerm); kBrightness: the intensity
/// residual predicts the previous intensity as gain I_i(u) + offset.
template <bool kBrightness>
void buildRows(const Warp& warp, const LevelCamera& camera, const ResidualParams& params, const Brightness& brightness,
               std::size_t m, RowScratch* scratch) {
  RowScratch& rows = *scratch;
  const float inv_c2 = 1.0f / (params.cauchy_c * params.cauchy_c);
  const float alpha = params.alpha_intensity;
  const float fx = camera.fx, fy = camera.fy;
  const float gain = brightness.gain, offset = brightness.offset;
  float* const J[6] = {rows.J[0].data(), rows.J[1].data(), rows.J[2].data(),
                        rows.J[3].data(), rows.J[4].data(), rows.J[5].data()};
  float* r_out = rows.r.data();
  float* w_out = rows.w.data();
  const float *x = rows.x.data(), *y = rows.y.data(), *z = rows.z.data();
  const float *X = rows.X.data(), *Y = rows.Y.data(), *Z = rows.Z.data(), *inv_Z = rows.inv_Z.data();
  const float *sI = rows.s[kLookupI].data(), *sIu = rows.s[kLookupIu].data(), *sIv = rows.s[kLookupIv].data();
  const float *sD = rows.s[kLookupD].data(), *sDu = rows.s[kLookupDu].data(), *sDv = rows.s[kLookupDv].data();
  const float* valid = rows.s[kLookupValid].data();
  const float *I = rows.I.data(), *wI = rows.wI.data(), *wD = rows.wD.data(), *gamma = rows.gamma.data();
  // The row columns and the gathered columns are separate buffers: no iteration reads what another
  // writes, which the compiler cannot prove through the many pointers (it would not vectorise).
#pragma GCC ivdep
  for (std::size_t j = 0; j < m; ++j) {
    const float iz = inv_Z[j];
    // intensity row
    {
      const float r = kBrightness ? sI[j] - (gain * I[j] + offset) : sI[j] - I[j];
      const float aw = alpha * wI[j];
      const float scaled = aw * r;
      const float gx = sIu[j] * fx * iz, gy = sIv[j] * fy * iz;
      const float gz = -(gx * X[j] + gy * Y[j]) * iz;
      writeRow(warp, x[j], y[j], z[j], gx, gy, gz, j, J);
      r_out[j] = r;
      w_out[j] = gamma[j] * cauchyWeight(scaled, inv_c2) * aw * aw;
    }
    // depth row
    {
      const std::size_t k = m + j;
      const float r = sD[j] - Z[j];
      const float wd = wD[j];
      const float scaled = wd * r;
      const float gx = sDu[j] * fx * iz, gy = sDv[j] * fy * iz;
      const float gz = -(gx * X[j] + gy * Y[j]) * iz - 1.0f;
      writeRow(warp, x[j], y[j], z[j], gx, gy, gz, k, J);
      r_out[k] = r;
      w_out[k] = valid[j] * gamma[j] * cauchyWeight(scaled, inv_c2) * wd * wd;
    }
  }
}

}  // namespace

void RowScratch::reserve(std::size_t pixels) {
  auto grow = [](std::vector<float>& column, std::size_t size) {
    if (column.size() < size) column.resize(size);
  };
  for (std::vector<float>* column : {&x, &y, &z, &X, &Y, &Z, &inv_Z, &I, &wI, &wD, &gamma}) grow(*column, pixels);
  for (std::vector<float>& column : s) grow(column, pixels);
  for (std::vector<float>& column : J) grow(column, 2 * pixels);
  grow(r, 2 * pixels);
  grow(w, 2 * pixels);
  if (block.size() < pixels) block.resize(pixels);
}

void BrightnessBlocks::reset(const LevelCamera& camera) {
  blocks_per_row = (camera.width + kBrightnessBlockPx - 1) / kBrightnessBlockPx;
  const std::size_t n = static_cast<std::size_t>(blocks_per_row) *
                        ((camera.height + kBrightnessBlockPx - 1) / kBrightnessBlockPx);
  w.assign(n, 0.0);  // no allocation once the buffers have held the largest level
  x.assign(n, 0.0);
  s.assign(n, 0.0);
}

void ClusterEvidence::reset(int num_labels) {
  cost_sum.assign(static_cast<std::size_t>(num_labels), 0.0);
  num_pixels.assign(static_cast<std::size_t>(num_labels), 0);
  prior_sum.assign(static_cast<std::size_t>(num_labels), 0.0);
  prior_count.assign(static_cast<std::size_t>(num_labels), 0);
}

void accumulateImageTerm(const DenseLevel& previous, const DenseLevel& current, const Warp& warp,
                         const float* gamma_of_label, const ResidualParams& params, RowScratch* scratch,
                         ImageNormalEquations* out, const Brightness* brightness, BrightnessBlocks* blocks) {
  const LevelCamera& camera = previous.camera;
  const std::size_t n = current.pixel.size();
  scratch->reserve(n);
  RowScratch& rows = *scratch;
  const float* lookup = previous.lookup.data();
  if (blocks != nullptr) blocks->reset(current.camera);
  // Gather: the pixels that take part (weight > 0, warped into the previous image, not hidden
  // there), with their warped points and the previous frame's samples.
  std::size_t m = 0;
  int num_depth_rows = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float gamma = gamma_of_label[current.label[i]];
    if (!(gamma > 0.0f)) continue;
    const float x = current.x_m[i], y = current.y_m[i], z = current.z_m[i];
    Warped p;
    if (!warpPoint(warp, camera, x, y, z, &p)) continue;
    float sample[kLookupChannels];
    bilinear(lookup, camera.width, p.u, p.v, sample);
    const bool has_depth = sample[kLookupValid] > kAllTapsValid;
    if (has_depth && sample[kLookupD] < p.Z - params.occlusion_gap_m) continue;  // hidden in the previous frame
    rows.x[m] = x;
    rows.y[m] = y;
    rows.z[m] = z;
    rows.X[m] = p.X;
    rows.Y[m] = p.Y;
    rows.Z[m] = p.Z;
    rows.inv_Z[m] = p.inv_Z;
    // The depth row only where the sample's four taps lie on one surface: a sample mixing two
    // surfaces measures neither, and its residual does not follow the linear model (Eq. 62).
    const bool depth_row = has_depth && smoothCellAt(lookup, camera.width, p.u, p.v);
    for (int k = 0; k < kLookupValid; ++k) rows.s[k][m] = sample[k];
    rows.s[kLookupValid][m] = depth_row ? 1.0f : 0.0f;
    rows.I[m] = current.intensity_at[i];
    rows.wI[m] = current.weight_I[i];
    rows.wD[m] = current.weight_D[i];
    rows.gamma[m] = gamma;
    if (blocks != nullptr) rows.block[m] = blocks->blockOf(current.pixel[i], camera.width);
    num_depth_rows += depth_row ? 1 : 0;
    ++m;
  }
  // Rows, branch-free over the gathered pixels: intensity (Eq. 61, r_I = I_{i-1}(W(u, T)) - I_i(u),
  // or with the brightness change r_I = I_{i-1}(W(u, T)) - (gain I_i(u) + offset)) in [0, m), depth
  // (Eq. 62, r_D = D_{i-1}(W(u, T)) - |T p|_z, weight 0 where the previous frame has no depth) in
  // [m, 2m). d/d eps of a residual with gradient g at the warped point P is [p x h, h], h = R^T g
  // (writeRow).
  if (brightness != nullptr) {
    buildRows<true>(warp, camera, params, *brightness, m, &rows);
  } else {
    buildRows<false>(warp, camera, params, Brightness(), m, &rows);
  }
  accumulateRows(rows, 2 * m, out);
  out->num_residuals += static_cast<int>(m) + num_depth_rows;
  if (brightness != nullptr && blocks != nullptr) accumulateBrightnessBlocks(rows, m, blocks);
}

void clusterEvidence(const DenseLevel& previous, const DenseLevel& current, const Warp& warp,
                     const float* previous_gamma_of_label, const ResidualParams& params, const Brightness& brightness,
                     ClusterEvidence* out, float max_pixel_cost) {
  const LevelCamera& camera = previous.camera;
  const float inv_c2 = 1.0f / (params.cauchy_c * params.cauchy_c);
  const float half_c2 = 0.5f * params.cauchy_c * params.cauchy_c;
  const float* lookup = previous.lookup.data();
  const std::uint8_t* previous_labels = previous.labels.ptr<std::uint8_t>(0);
  const std::size_t n = current.pixel.size();
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t k = current.label[i];
    Warped p;
    if (!warpPoint(warp, camera, current.x_m[i], current.y_m[i], current.z_m[i], &p)) continue;
    float s[kLookupChannels];
    bilinear(lookup, camera.width, p.u, p.v, s);
    const bool has_depth = s[kLookupValid] > kAllTapsValid;
    if (has_depth && s[kLookupD] < p.Z - params.occlusion_gap_m) continue;  // hidden in the previous frame
    // Temporal prior, Eq. 30: the previous score at the nearest previous pixel.
    const int c = static_cast<int>(p.u + 0.5f), r = static_cast<int>(p.v + 0.5f);
    out->prior_sum[k] += previous_gamma_of_label[previous_labels[static_cast<std::size_t>(r) * camera.width + c]];
    ++out->prior_count[k];
    if (!has_depth) continue;
    // gain 1, offset 0: 1 * I + 0 is I exactly, Eq. 61 as it stands
    const float predicted_I = brightness.gain * current.intensity_at[i] + brightness.offset;
    const float scaled_I = params.alpha_intensity * current.weight_I[i] * (s[kLookupI] - predicted_I);
    const float scaled_D = current.weight_D[i] * (s[kLookupD] - p.Z);
    out->cost_sum[k] += std::min(cauchy(scaled_I, inv_c2, half_c2) + cauchy(scaled_D, inv_c2, half_c2), max_pixel_cost);
    ++out->num_pixels[k];
  }
}

void accumulateBrightness(const DenseLevel& previous, const DenseLevel& current, const Warp& warp,
                          const float* previous_gamma_of_label, const ResidualParams& params,
                          BrightnessBlocks* blocks) {
  const LevelCamera& camera = previous.camera;
  blocks->reset(current.camera);
  const float* lookup = previous.lookup.data();
  const std::uint8_t* previous_labels = previous.labels.ptr<std::uint8_t>(0);
  const std::size_t n = current.pixel.size();
  for (std::size_t i = 0; i < n; ++i) {
    Warped p;
    if (!warpPoint(warp, camera, current.x_m[i], current.y_m[i], current.z_m[i], &p)) continue;
    float s[kLookupChannels];
    bilinear(lookup, camera.width, p.u, p.v, s);
    const bool has_depth = s[kLookupValid] > kAllTapsValid;
    if (has_depth && s[kLookupD] < p.Z - params.occlusion_gap_m) continue;  // hidden
    if (!has_depth || !smoothCellAt(lookup, camera.width, p.u, p.v)) continue;  // mixes two surfaces
    const int c = static_cast<int>(p.u + 0.5f), r = static_cast<int>(p.v + 0.5f);
    const float prior_gamma = previous_gamma_of_label[previous_labels[static_cast<std::size_t>(r) * camera.width + c]];
    const float I = current.intensity_at[i];
    const float wu = prior_gamma * unclipped(I, s[kLookupI]);
    const std::size_t b = static_cast<std::size_t>(blocks->blockOf(current.pixel[i], camera.width));
    blocks->w[b] += wu;
    blocks->x[b] += wu * (I - 0.5f);
    blocks->s[b] += wu * s[kLookupI];
  }
}

}  // namespace ltlo::segmentation::detail
