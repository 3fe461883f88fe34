#include "ltlo/system/hindsight_masks.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include <opencv2/imgcodecs.hpp>

#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"

namespace ltlo::system {

namespace {

constexpr char kToDynamic = 1, kToStatic = 2;  // flip_ values
/// Consecutive frames a thread relabels in one go (forEachFrame): a re-judged stretch prepares each of
/// its frames once on one thread.
constexpr std::size_t kFramesPerChunk = 128;
/// A free-space view must face within this of the frame's optical axis (cos 100 deg): a view facing
/// away sees none of the frame's surface, and skipping it saves its projections.
constexpr double kMinViewAxisCos = -0.17;
/// Closer than this in front of a view, a point says nothing of what the view saw (m).
constexpr double kMinViewDepth_m = 0.1;

inline bool validDepth(float z) { return z > 0.0f && z < std::numeric_limits<float>::infinity(); }

/// Each scale x scale block of `raw` into `coarse` (pre-sized): the nearest depth of the block, so a
/// block on a depth edge belongs to the surface in front (the one a mask must cover).
void nearestDepthPerBlock(const cv::Mat& raw, int scale, cv::Mat* coarse) {
  for (int r = 0; r < coarse->rows; ++r) {
    float* out = coarse->ptr<float>(r);
    for (int c = 0; c < coarse->cols; ++c) {
      float nearest = std::numeric_limits<float>::max();
      for (int dv = 0; dv < scale; ++dv) {
        const float* row = raw.ptr<float>(r * scale + dv) + c * scale;
        for (int du = 0; du < scale; ++du) {
          if (validDepth(row[du])) nearest = std::min(nearest, row[du]);
        }
      }
      out[c] = nearest == std::numeric_limits<float>::max() ? 0.0f : nearest;
    }
  }
}

/// Sorted frame times of `trajectory` in `map` with their poses.
struct PoseLookup {
  std::vector<double> t_s;
  std::vector<SE3> T_w_c;

  PoseLookup(const std::vector<FramePose>& trajectory, map::MapId map) {
    std::vector<const FramePose*> sorted;
    for (const FramePose& pose : trajectory) {
      if (pose.map == map) sorted.push_back(&pose);
    }
    std::sort(sorted.begin(), sorted.end(), [](const FramePose* a, const FramePose* b) { return a->t_s < b->t_s; });
    for (const FramePose* pose : sorted) {
      t_s.push_back(pose->t_s);
      T_w_c.push_back(pose->T_w_c);
    }
  }
  /// The pose at time t (within 1 us), or null.
  const SE3* find(double t) const {
    const auto it = std::lower_bound(t_s.begin(), t_s.end(), t - 1e-6);
    if (it == t_s.end() || *it > t + 1e-6) return nullptr;
    return &T_w_c[static_cast<std::size_t>(it - t_s.begin())];
  }
};

}  // namespace

FreeSpaceView FreeSpaceView::fromDepth(const cv::Mat& depth_m, const SE3& T_w_c, double t_s, int view_scale) {
  LTLO_ASSERT(depth_m.type() == CV_32F && view_scale > 0 && depth_m.cols % view_scale == 0 &&
                  depth_m.rows % view_scale == 0,
              "depth " << depth_m.cols << "x" << depth_m.rows << " type " << depth_m.type() << ", scale " << view_scale);
  FreeSpaceView view;
  view.t_s = t_s;
  const SE3 T_c_w = T_w_c.inverse();
  view.R_c_w = T_c_w.rotationMatrix();
  view.t_c_w = T_c_w.translation();
  view.axis_w = T_w_c.rotationMatrix().col(2);
  view.view_scale = view_scale;
  cv::Mat blocks(depth_m.rows / view_scale, depth_m.cols / view_scale, CV_32F);
  nearestDepthPerBlock(depth_m, view_scale, &blocks);
  // The nearest of the 3 x 3 blocks around, unknown where any is unknown: a depth edge is the surface in
  // front for a block either side, so neither a pose error of a pixel nor a hole sees past it.
  view.depth_m.create(blocks.rows, blocks.cols, CV_32F);
  for (int r = 0; r < blocks.rows; ++r) {
    float* out = view.depth_m.ptr<float>(r);
    for (int c = 0; c < blocks.cols; ++c) {
      float nearest = std::numeric_limits<float>::max();
      for (int nr = std::max(0, r - 1); nr <= std::min(blocks.rows - 1, r + 1); ++nr) {
        const float* row = blocks.ptr<float>(nr);
        for (int nc = std::max(0, c - 1); nc <= std::min(blocks.cols - 1, c + 1); ++nc) {
          nearest = row[nc] > 0.0f ? std::min(nearest, row[nc]) : 0.0f;
          if (nearest == 0.0f) break;
        }
        if (nearest == 0.0f) break;
      }
      out[c] = nearest;
    }
  }
  return view;
}

double measureDepthNoise(const std::vector<cv::Mat>& depths_m, const segmentation::DepthKMeansOptions& clusters) {
  std::vector<float> second;  // second differences of inverse depth
  for (const cv::Mat& depth : depths_m) {
    LTLO_ASSERT(depth.type() == CV_32F, "depth type " << depth.type());
    for (int r = 0; r < depth.rows; r += 2) {
      const float* z = depth.ptr<float>(r);
      for (int c = 1; c + 1 < depth.cols; ++c) {
        if (!validDepth(z[c - 1]) || !validDepth(z[c]) || !validDepth(z[c + 1])) continue;
        const float gap = static_cast<float>(clusters.gapThreshold(z[c]));
        if (std::abs(z[c - 1] - z[c]) >= gap || std::abs(z[c + 1] - z[c]) >= gap) continue;
        second.push_back(1.0f / z[c - 1] - 2.0f / z[c] + 1.0f / z[c + 1]);
      }
    }
  }
  if (second.empty()) return 0.0;
  const auto middle = second.begin() + static_cast<std::ptrdiff_t>(second.size() / 2);
  std::nth_element(second.begin(), middle, second.end());
  const float median = *middle;
  for (float& e : second) e = std::abs(e - median);
  std::nth_element(second.begin(), middle, second.end());
  return 1.4826 * static_cast<double>(*middle) / std::sqrt(6.0);
}

HindsightMaskOptions HindsightMaskOptions::from(const Settings& settings) {
  HindsightMaskOptions options;
  options.clusters = segmentation::DepthKMeansOptions::from(settings.segmentation);
  options.label_width = settings.dense.width;
  options.label_height = settings.dense.height;
  options.static_threshold = settings.segmentation.static_threshold;
  options.min_beta = settings.local_mapping.min_point_beta;
  options.min_points = settings.segmentation.hindsight_min_points;
  options.ray_tolerance_m = settings.segmentation.hindsight_ray_tolerance_m;
  options.vote_radius_m = settings.segmentation.hindsight_vote_radius_m;
  options.to_static = settings.segmentation.hindsight_to_static;
  options.static_share = settings.segmentation.hindsight_static_share;
  options.free_space = settings.segmentation.hindsight_free_space;
  options.free_space_views = settings.segmentation.hindsight_free_space_views;
  options.free_space_max_views = settings.segmentation.hindsight_free_space_max_views;
  options.free_space_frame_interval_s = settings.segmentation.hindsight_free_space_frame_interval_s;
  options.free_space_tolerance_m = settings.segmentation.hindsight_free_space_tolerance_m;
  options.depth_noise_m = settings.recon.depth_noise_m;
  options.rejudge = RejudgeOptions::from(settings);
  return options;
}

HindsightRelabeller::HindsightRelabeller(const CameraModel& camera, const HindsightMaskOptions& options)
    : camera_(camera), options_(options), kmeans_(options.clusters) {
  const int width = camera.pinhole().width(), height = camera.pinhole().height();
  LTLO_ASSERT(options.label_width > 0 && width % options.label_width == 0 &&
                  options.label_height * (width / options.label_width) == height,
              "labels " << options.label_width << "x" << options.label_height << " do not divide the camera's "
                        << width << "x" << height);
  scale_ = width / options.label_width;
  label_camera_ = camera.pinhole().scaled(1.0 / scale_);
  label_depth_m_.create(options.label_height, options.label_width, CV_32F);
  // Each label pixel's ray through the centre of its block (z = 1, the lens undone once).
  bearings_.resize(static_cast<std::size_t>(options.label_width) * static_cast<std::size_t>(options.label_height));
  for (int r = 0; r < options.label_height; ++r) {
    for (int c = 0; c < options.label_width; ++c) {
      const double half = 0.5 * (scale_ - 1);
      const std::optional<Vec3> ray = camera.unproject(Vec2(c * scale_ + half, r * scale_ + half));
      bearings_[static_cast<std::size_t>(r * options.label_width + c)] =
          ray && ray->z() > 0.0 ? Vec2(ray->x() / ray->z(), ray->y() / ray->z())
                                : Vec2(std::numeric_limits<double>::quiet_NaN(), 0.0);
    }
  }
  // The raw image's field on the normalised plane: its border pixels' rays (for a pinhole, the image).
  field_min_ = Vec2::Constant(std::numeric_limits<double>::max());
  field_max_ = Vec2::Constant(std::numeric_limits<double>::lowest());
  const auto extend = [&](double u, double v) {
    const std::optional<Vec3> ray = camera.unproject(Vec2(u, v));
    if (!ray) return;
    field_min_ = field_min_.cwiseMin(ray->head<2>());
    field_max_ = field_max_.cwiseMax(ray->head<2>());
  };
  for (int u = 0; u < width; ++u) {
    extend(u, 0.0);
    extend(u, height - 1.0);
  }
  for (int v = 0; v < height; ++v) {
    extend(0.0, v);
    extend(width - 1.0, v);
  }
  grid_cols_ = (options.label_width + kFreeSpaceStride - 1) / kFreeSpaceStride;
  grid_rows_ = (options.label_height + kFreeSpaceStride - 1) / kFreeSpaceStride;
}

double HindsightRelabeller::freeSpaceTolerance(double z_m, double gap_m) const {
  if (options_.free_space_tolerance_m <= 0.0) return gap_m;
  const double noise_m = std::max(options_.depth_noise_m, options_.measured_noise_m);
  return std::min(gap_m, options_.free_space_tolerance_m + 3.0 * noise_m * z_m * z_m);
}

Vec3 HindsightRelabeller::backProject(int c, int r) const {
  const double z = label_depth_m_.ptr<float>(r)[c];
  return Vec3((c - label_camera_.cx()) / label_camera_.fx() * z, (r - label_camera_.cy()) / label_camera_.fy() * z, z);
}

bool HindsightRelabeller::seenThrough(const Vec3& x_w, const MapPointRecord& point) const {
  const double tolerance_sq = options_.ray_tolerance_m * options_.ray_tolerance_m;
  for (const Vec3& centre_w : point.observer_centres_w) {
    const Vec3 ray = point.p_w - centre_w;
    const double length_sq = ray.squaredNorm();
    if (length_sq <= 0.0) continue;
    const double s = std::clamp((x_w - centre_w).dot(ray) / length_sq, 0.0, 1.0);
    if ((centre_w + s * ray - x_w).squaredNorm() < tolerance_sq) return true;
  }
  return false;
}

std::optional<Vec2> HindsightRelabeller::projectInField(const Vec3& p_c) const {
  const Vec2 x_n(p_c.x() / p_c.z(), p_c.y() / p_c.z());
  if (x_n.x() < field_min_.x() || x_n.y() < field_min_.y() || x_n.x() > field_max_.x() || x_n.y() > field_max_.y()) {
    return std::nullopt;
  }
  return camera_.project(p_c);
}

int HindsightRelabeller::viewState(const FreeSpaceView& view, const Vec3& x_w) const {
  const Vec3 x_v = view.R_c_w * x_w + view.t_c_w;
  if (x_v.z() < kMinViewDepth_m) return -1;
  const std::optional<Vec2> u = projectInField(x_v);
  if (!u) return -1;
  const int vc = static_cast<int>(std::floor(u->x() / view.view_scale));
  const int vr = static_cast<int>(std::floor(u->y() / view.view_scale));
  if (vc < 0 || vr < 0 || vc >= view.depth_m.cols || vr >= view.depth_m.rows) return -1;
  const float depth = view.depth_m.ptr<float>(vr)[vc];
  if (depth <= 0.0f) return -1;
  const double gap = options_.clusters.gapThreshold(x_v.z());
  if (depth < x_v.z() - gap) return -1;  // the view's surface stands in front: it did not see here
  return depth > x_v.z() + freeSpaceTolerance(x_v.z(), gap) ? 1 : 0;  // past the point: free space
}

void HindsightRelabeller::selectViews(const SE3& T_w_c, const std::vector<FreeSpaceView>& views, double t_s) {
  const Vec3 axis_w = T_w_c.rotationMatrix().col(2);
  active_views_.clear();
  for (const FreeSpaceView& view : views) {
    if (std::abs(view.t_s - t_s) < (view.keyframe ? 1e-6 : kFrameViewMinGapS) ||
        view.axis_w.dot(axis_w) < kMinViewAxisCos) {
      continue;
    }
    active_views_.push_back(&view);
  }
  const std::size_t max_views = static_cast<std::size_t>(options_.free_space_max_views);
  if (max_views == 0 || active_views_.size() <= max_views) return;
  // Probes: every n-th of the frame's samples in raster order, about kFreeSpaceProbes of them.
  const std::size_t every = std::max<std::size_t>(1, samples_.size() / kFreeSpaceProbes);
  view_scores_.clear();
  for (std::size_t v = 0; v < active_views_.size(); ++v) {
    int score = 0;
    for (std::size_t n = 0; n < samples_.size(); n += every) {
      score += 1 + viewState(*active_views_[v], samples_[n].x_w);  // -1, 0, 1 -> 0, 1, 2
    }
    view_scores_.emplace_back(-score, static_cast<int>(v));
  }
  std::partial_sort(view_scores_.begin(), view_scores_.begin() + static_cast<std::ptrdiff_t>(max_views),
                    view_scores_.end());
  ranked_views_.clear();
  for (std::size_t k = 0; k < max_views && view_scores_[k].first < 0; ++k) {
    ranked_views_.push_back(active_views_[static_cast<std::size_t>(view_scores_[k].second)]);
  }
  active_views_.swap(ranked_views_);
}

void HindsightRelabeller::sampleFreeSpace(const SE3& T_w_c, const std::vector<FreeSpaceView>& views, double t_s,
                                          int num_regions) {
  const std::size_t num_samples = static_cast<std::size_t>(grid_cols_) * static_cast<std::size_t>(grid_rows_);
  sample_state_.assign(num_samples, -1);
  sample_x_c_.resize(num_samples);
  fs_violated_.assign(static_cast<std::size_t>(num_regions), 0);
  // The frame's samples: the label pixel at the middle of each grid cell, with a region and a ray.
  samples_.clear();
  for (int gr = 0; gr < grid_rows_; ++gr) {
    const int r = std::min(label_depth_m_.rows - 1, gr * kFreeSpaceStride + kFreeSpaceStride / 2);
    for (int gc = 0; gc < grid_cols_; ++gc) {
      const int c = std::min(label_depth_m_.cols - 1, gc * kFreeSpaceStride + kFreeSpaceStride / 2);
      const int region = regions_.ptr<int>(r)[c];
      if (region < 0) continue;
      const Vec2& bearing = bearings_[static_cast<std::size_t>(r * label_depth_m_.cols + c)];
      if (std::isnan(bearing.x())) continue;
      const double z = label_depth_m_.ptr<float>(r)[c];
      const Vec3 x_c(bearing.x() * z, bearing.y() * z, z);
      samples_.push_back({gr * grid_cols_ + gc, region, x_c, T_w_c * x_c});
    }
  }
  selectViews(T_w_c, views, t_s);
  if (active_views_.empty()) return;
  const int needed = options_.free_space_views;
  for (const FreeSpaceSample& sample : samples_) {
    int through = 0;
    bool seen = false;
    for (const FreeSpaceView* view : active_views_) {
      const int state = viewState(*view, sample.x_w);
      if (state < 0) continue;
      seen = true;
      if (state > 0 && ++through >= needed) break;
    }
    if (!seen) continue;
    sample_state_[static_cast<std::size_t>(sample.cell)] = through >= needed ? 1 : 0;
    sample_x_c_[static_cast<std::size_t>(sample.cell)] = sample.x_c;
    fs_violated_[static_cast<std::size_t>(sample.region)] += through >= needed;
  }
}

int HindsightRelabeller::nearestSampleState(int c, int r, int region, const Vec3& x_c) const {
  const int gc0 = c / kFreeSpaceStride, gr0 = r / kFreeSpaceStride;
  double nearest_sq = std::numeric_limits<double>::max();
  int state = -1;
  for (int gr = std::max(0, gr0 - 1); gr <= std::min(grid_rows_ - 1, gr0 + 1); ++gr) {
    for (int gc = std::max(0, gc0 - 1); gc <= std::min(grid_cols_ - 1, gc0 + 1); ++gc) {
      const std::size_t sample = static_cast<std::size_t>(gr * grid_cols_ + gc);
      if (sample_state_[sample] < 0) continue;
      const int sr = std::min(label_depth_m_.rows - 1, gr * kFreeSpaceStride + kFreeSpaceStride / 2);
      const int sc = std::min(label_depth_m_.cols - 1, gc * kFreeSpaceStride + kFreeSpaceStride / 2);
      if (regions_.ptr<int>(sr)[sc] != region) continue;
      const double distance_sq = (sample_x_c_[sample] - x_c).squaredNorm();
      if (distance_sq < nearest_sq) {
        nearest_sq = distance_sq;
        state = sample_state_[sample];
      }
    }
  }
  return state;
}

int HindsightRelabeller::splitClusters() {
  const cv::Mat& labels = clusters_.labels;
  const int K = clusters_.num_clusters, w = labels.cols, h = labels.rows;
  if (regions_.rows != h || regions_.cols != w) regions_.create(h, w, CV_32S);
  regions_.setTo(-1);
  int num_regions = 0;
  for (int start = 0; start < w * h; ++start) {
    const int start_r = start / w, start_c = start % w;
    if (labels.ptr<std::uint8_t>(start_r)[start_c] >= K || regions_.ptr<int>(start_r)[start_c] >= 0) continue;
    const int region = num_regions++;
    const std::uint8_t cluster = labels.ptr<std::uint8_t>(start_r)[start_c];
    regions_.ptr<int>(start_r)[start_c] = region;
    stack_.assign(1, start);
    while (!stack_.empty()) {
      const int pixel = stack_.back();
      stack_.pop_back();
      const int r = pixel / w, c = pixel % w;
      const float z = label_depth_m_.ptr<float>(r)[c];
      const int neighbours[4][2] = {{r - 1, c}, {r + 1, c}, {r, c - 1}, {r, c + 1}};
      for (const auto& [nr, nc] : neighbours) {
        if (nr < 0 || nc < 0 || nr >= h || nc >= w) continue;
        if (labels.ptr<std::uint8_t>(nr)[nc] != cluster || regions_.ptr<int>(nr)[nc] >= 0) continue;
        const float nz = label_depth_m_.ptr<float>(nr)[nc];
        if (std::abs(nz - z) >= options_.clusters.gapThreshold(0.5 * (nz + z))) continue;
        regions_.ptr<int>(nr)[nc] = region;
        stack_.push_back(nr * w + nc);
      }
    }
  }
  return num_regions;
}

HindsightFrameResult HindsightRelabeller::relabel(const cv::Mat& depth_m, const SE3& T_w_c,
                                                  const std::vector<MapPointRecord>& points, cv::Mat* mask,
                                                  const std::vector<FreeSpaceView>& views, double t_s) {
  const int width = camera_.pinhole().width(), height = camera_.pinhole().height();
  LTLO_ASSERT(depth_m.type() == CV_32F && depth_m.cols == width && depth_m.rows == height,
              "depth " << depth_m.cols << "x" << depth_m.rows << " type " << depth_m.type());
  LTLO_ASSERT(mask->type() == CV_8UC1 && mask->cols == width && mask->rows == height,
              "mask " << mask->cols << "x" << mask->rows << " type " << mask->type());
  nearestDepthPerBlock(depth_m, scale_, &label_depth_m_);
  kmeans_.cluster(label_depth_m_, label_camera_, &clusters_);
  HindsightFrameResult result;
  result.clusters = clusters_.num_clusters;
  if (result.clusters == 0) return result;
  // Regions: the depth-continuous pieces of each cluster (a cluster may hold a box's edge and the wall
  // beside it, which the online step labels as one; here each piece is judged alone).
  const int R = splitClusters();
  result.regions = R;

  // The online mask's dynamic share of each region (its pixel at each block's corner).
  pixels_.assign(static_cast<std::size_t>(R), 0);
  dynamic_pixels_.assign(static_cast<std::size_t>(R), 0);
  for (int r = 0; r < regions_.rows; ++r) {
    const int* regions = regions_.ptr<int>(r);
    const std::uint8_t* online = mask->ptr<std::uint8_t>(r * scale_);
    for (int c = 0; c < regions_.cols; ++c) {
      if (regions[c] < 0) continue;
      ++pixels_[regions[c]];
      dynamic_pixels_[regions[c]] += online[c * scale_] != 0;
    }
  }

  // Eq. 56's votes of the static points.
  voters_.clear();
  vote_sum_.assign(static_cast<std::size_t>(R), 0.0);
  beta_sum_.assign(static_cast<std::size_t>(R), 0.0);
  votes_.assign(static_cast<std::size_t>(R), 0);
  const SE3 T_c_w = T_w_c.inverse();
  for (const MapPointRecord& point : points) {
    if (point.beta < options_.min_beta) continue;
    const Vec3 p_c = T_c_w * point.p_w;
    if (p_c.z() <= 0.05) continue;
    const std::optional<Vec2> u = projectInField(p_c);
    if (!u) continue;
    const int ui = static_cast<int>(std::lround(u->x())), vi = static_cast<int>(std::lround(u->y()));
    if (ui < 0 || vi < 0 || ui >= width || vi >= height) continue;
    const float z_image = depth_m.ptr<float>(vi)[ui];
    if (!validDepth(z_image)) continue;
    const int region = regions_.ptr<int>(vi / scale_)[ui / scale_];
    if (region < 0) continue;
    const double gap = options_.clusters.gapThreshold(z_image);
    // Seen past: the frame's surface lies behind the point by more than depth noise.
    if (p_c.z() < z_image - gap) continue;
    const double d = std::max(0.0, p_c.z() - z_image);
    if (d > gap && !seenThrough(T_w_c * (p_c * (z_image / p_c.z())), point)) continue;
    // Behind the surface by more than depth noise, and seen through it: the surface stood where the
    // map saw free space, whatever the distance (Eq. 56's lambda_p d grades an online guess; here the
    // final map and the keyframe's ray decide).
    const double vote = d > gap ? 1.0 : 0.0;
    vote_sum_[region] += point.beta * vote;
    voters_.push_back({region, backProject(ui / scale_, vi / scale_), vote > 0.0});
    beta_sum_[region] += point.beta;
    ++votes_[region];
  }

  flip_.assign(static_cast<std::size_t>(R), 0);
  fs_flip_.assign(static_cast<std::size_t>(R), 0);
  const auto online_static = [&](int k) { return 2 * dynamic_pixels_[k] < pixels_[k]; };
  // Free space: regions the online mask calls static where keyframes saw through min_points samples.
  if (options_.free_space && !views.empty()) {
    sampleFreeSpace(T_w_c, views, t_s, R);
    result.views_asked = static_cast<int>(active_views_.size());
    for (int k = 0; k < R; ++k) {
      if (!online_static(k) || fs_violated_[k] < options_.min_points) continue;
      fs_flip_[k] = 1;
      ++result.regions_free_space;
    }
  }
  for (int k = 0; k < R; ++k) {
    if (votes_[k] < options_.min_points || beta_sum_[k] <= 0.0) continue;
    ++result.regions_voted;
    const double gamma_prior = 1.0 - vote_sum_[k] / beta_sum_[k];  // Eq. 56
    if (online_static(k) && gamma_prior < options_.static_threshold) {
      flip_[k] = kToDynamic;
      ++result.regions_flipped;
    }
    // Free space vetoes: a surface keyframes saw through is no static surface, whatever points lie on it
    // (points made on a box while it stood there, never seen again).
    const bool seen_through = options_.free_space && !views.empty() && fs_violated_[k] >= options_.min_points;
    if (options_.to_static && !online_static(k) && gamma_prior >= options_.static_share && !seen_through) {
      flip_[k] = kToStatic;
      ++result.regions_to_static;
    }
  }
  for (int k = 0; k < R; ++k) result.regions_flipped += fs_flip_[k] && flip_[k] != kToDynamic;
  if (result.regions_flipped == 0 && result.regions_to_static == 0) return result;
  // In a flipped region, the pixels whose nearest voter (3-D) lies within vote_radius_m and votes the
  // region's new label: the votes speak for the surface around them, not for a far end of the region (a
  // box's side face and the floor it stands on are one depth-continuous region).
  const double radius_sq = options_.vote_radius_m * options_.vote_radius_m;
  const auto fill_block = [&](int r, int c, std::uint8_t value) {  // label pixel (c, r) -> its raw block
    for (int dv = 0; dv < scale_; ++dv) {
      std::uint8_t* out = mask->ptr<std::uint8_t>(r * scale_ + dv) + c * scale_;
      std::fill(out, out + scale_, value);
    }
  };
  for (int r = 0; r < regions_.rows; ++r) {
    const int* regions = regions_.ptr<int>(r);
    for (int c = 0; c < regions_.cols; ++c) {
      if (regions[c] < 0 || (!flip_[regions[c]] && !fs_flip_[regions[c]])) continue;
      if (fs_flip_[regions[c]]) {
        // The nearest free-space sample of the region says for the pixel.
        const Vec2& bearing = bearings_[static_cast<std::size_t>(r * regions_.cols + c)];
        const double z = label_depth_m_.ptr<float>(r)[c];
        if (!std::isnan(bearing.x()) &&
            nearestSampleState(c, r, regions[c], Vec3(bearing.x() * z, bearing.y() * z, z)) == 1) {
          fill_block(r, c, 255);
          continue;
        }
        if (!flip_[regions[c]]) continue;
      }
      const bool to_static = flip_[regions[c]] == kToStatic;
      const Vec3 x_c = backProject(c, r);
      double nearest_sq = radius_sq;
      bool dynamic = false;
      for (const Voter& voter : voters_) {
        if (voter.region != regions[c]) continue;
        const double distance_sq = (voter.x_c - x_c).squaredNorm();
        if (distance_sq < nearest_sq) {
          nearest_sq = distance_sq;
          dynamic = voter.dynamic;
        }
      }
      if (nearest_sq >= radius_sq || dynamic == to_static) continue;
      fill_block(r, c, to_static ? 0 : 255);
    }
  }
  return result;
}

namespace {

/// Runs fn(worker, frame position) for every position of `frames` on num_threads threads (worker 0 is
/// the caller), each thread taking every num_threads-th chunk of `chunk` consecutive frames, in order
/// (a re-judged stretch then meets its frames in order on one thread, which prepares each once). The
/// first exception stops the others at their next frame and is rethrown after all have joined.
template <typename Fn>
void forEachFrame(std::size_t num_frames, int num_threads, Fn&& fn, std::size_t chunk = 1) {
  std::atomic<bool> failed{false};
  std::exception_ptr first_error;
  std::mutex error_mutex;  // guards first_error
  auto work = [&](int worker) {
    try {
      for (std::size_t begin = static_cast<std::size_t>(worker) * chunk; begin < num_frames && !failed.load();
           begin += static_cast<std::size_t>(num_threads) * chunk) {
        for (std::size_t n = begin; n < std::min(num_frames, begin + chunk) && !failed.load(); ++n) fn(worker, n);
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!first_error) first_error = std::current_exception();
      failed = true;
    }
  };
  std::vector<std::thread> threads;
  for (int worker = 1; worker < num_threads; ++worker) threads.emplace_back(work, worker);
  work(0);
  for (std::thread& thread : threads) thread.join();
  if (first_error) std::rethrow_exception(first_error);
}

}  // namespace

HindsightMaskResult writeHindsightMasks(const io::SequenceReader& reader, const std::vector<FramePose>& trajectory,
                                        const std::vector<KeyFrameRecord>& keyframes, map::MapId points_map, const std::vector<MapPointRecord>& points,
                                        const CameraModel& camera, const HindsightMaskOptions& options,
                                        const std::string& out_dir, const std::vector<FramePose>& trajectory_online) {
  namespace fs = std::filesystem;
  const auto start = std::chrono::steady_clock::now();
  std::error_code error;
  fs::create_directories(out_dir, error);
  if (error) throw InputError(out_dir, 0, "cannot create the hindsight mask folder: " + error.message());

  const PoseLookup poses(trajectory, points_map);
  std::vector<int> frames;           // with an online mask
  std::vector<const SE3*> frame_poses;  // their final poses (null: none in points_map)
  for (int i = 0; i < reader.frameCount(); ++i) {
    if (reader.frameFiles(i).mask_path.empty()) continue;
    frames.push_back(i);
    frame_poses.push_back(poses.find(reader.frameFiles(i).t_s));
  }
  const int num_threads = std::max(1, std::min<int>(options.num_threads, static_cast<int>(frames.size())));
  HindsightMaskResult total;

  // The free-space views: the depth of every keyframe of points_map at its final pose, at twice the label
  // step, and of a frame every free_space_frame_interval_s between them.
  std::vector<FreeSpaceView> views;
  if (options.free_space) {
    std::vector<std::pair<double, int>> frame_times;  // every frame of the reader, by time
    for (int i = 0; i < reader.frameCount(); ++i) frame_times.emplace_back(reader.frameFiles(i).t_s, i);
    std::sort(frame_times.begin(), frame_times.end());
    struct ViewSource {
      int frame = 0;
      double t_s = 0.0;
      SE3 T_w_c;
      bool keyframe = true;
    };
    std::vector<ViewSource> sources;
    for (const KeyFrameRecord& keyframe : keyframes) {
      if (keyframe.map != points_map.value) continue;
      const auto it = std::lower_bound(frame_times.begin(), frame_times.end(),
                                       std::make_pair(keyframe.t_s - 1e-6, std::numeric_limits<int>::min()));
      if (it == frame_times.end() || it->first > keyframe.t_s + 1e-6) continue;
      sources.push_back({it->second, keyframe.t_s, keyframe.T_w_c});
    }
    total.free_space_views = static_cast<int>(sources.size());
    if (options.free_space_frame_interval_s > 0.0 && !poses.t_s.empty()) {
      // At most kMaxFrameViews over the final poses' span; a keyframe's own frame is a view already.
      const double span_s = poses.t_s.back() - poses.t_s.front();
      const double interval_s = std::max(options.free_space_frame_interval_s, span_s / kMaxFrameViews);
      std::vector<char> is_keyframe(static_cast<std::size_t>(reader.frameCount()), 0);
      for (const ViewSource& source : sources) is_keyframe[static_cast<std::size_t>(source.frame)] = 1;
      double next_t_s = -std::numeric_limits<double>::infinity();
      for (const auto& [t_s, index] : frame_times) {
        const SE3* T_w_c = poses.find(t_s);
        if (T_w_c == nullptr || t_s < next_t_s) continue;
        next_t_s = t_s + interval_s - 1e-6;
        if (is_keyframe[static_cast<std::size_t>(index)]) continue;
        sources.push_back({index, t_s, *T_w_c, /*keyframe=*/false});
        ++total.free_space_frame_views;
      }
    }
    const int view_scale = 2 * (camera.pinhole().width() / options.label_width);
    views.resize(sources.size());
    forEachFrame(sources.size(), num_threads, [&](int, std::size_t n) {
      const io::RgbdImuFrame frame = reader.load(sources[n].frame, /*with_colour=*/false);
      if (frame.depth_m.empty()) throw InputError(reader.frameFiles(sources[n].frame).depth_path, 0, "cannot read the depth");
      views[n] = FreeSpaceView::fromDepth(frame.depth_m, sources[n].T_w_c, sources[n].t_s, view_scale);
      views[n].keyframe = sources[n].keyframe;
    });
  }

  // Re-judging (hindsight_rejudge.h): each frame's online pose, its previous frame and its reference
  // frame (the newest at least a reference baseline earlier) among `frames`.
  const bool rejudging = options.rejudge.enable && !trajectory_online.empty();
  std::vector<RejudgePoses> rejudge_poses(frames.size());
  std::vector<int> reference_of(frames.size(), -1);
  if (rejudging) {
    std::vector<std::pair<double, std::size_t>> online;  // time, index into trajectory_online
    for (std::size_t k = 0; k < trajectory_online.size(); ++k) online.emplace_back(trajectory_online[k].t_s, k);
    std::sort(online.begin(), online.end());
    for (std::size_t n = 0; n < frames.size(); ++n) {
      const double t_s = reader.frameFiles(frames[n]).t_s;
      rejudge_poses[n].T_w_c_final = frame_poses[n];
      const auto it = std::lower_bound(online.begin(), online.end(), std::make_pair(t_s - 1e-6, std::size_t{0}));
      if (it != online.end() && it->first <= t_s + 1e-6) {
        const FramePose& pose = trajectory_online[it->second];
        rejudge_poses[n].T_w_c_online = &pose.T_w_c;
        rejudge_poses[n].online_map = pose.map.value;
      }
    }
    const double baseline_s = options.rejudge.reference_baseline_s;
    if (baseline_s > 0.0) {
      std::size_t m = 0;
      for (std::size_t n = 0; n < frames.size(); ++n) {
        const double t_s = reader.frameFiles(frames[n]).t_s;
        while (m + 1 < n && reader.frameFiles(frames[m + 1]).t_s <= t_s - baseline_s + 1e-3) ++m;
        if (m < n && reader.frameFiles(frames[m]).t_s <= t_s - baseline_s + 1e-3) reference_of[n] = static_cast<int>(m);
      }
    }
  }
  std::shared_ptr<const Undistorter> undistorter;
  if (rejudging) undistorter = std::make_shared<const Undistorter>(camera);

  // The sensor's depth noise, measured in kNoiseSampleFrames frames spread over the run: a sensor noisier
  // than Recon.DepthNoise says would see through static walls with the free-space tolerance.
  HindsightMaskOptions run_options = options;
  if (options.free_space && options.free_space_tolerance_m > 0.0 && !views.empty()) {
    const std::size_t count = std::min<std::size_t>(frames.size(), kNoiseSampleFrames);
    std::vector<cv::Mat> depths(count);
    forEachFrame(count, num_threads, [&](int, std::size_t k) {
      const int index = frames[k * frames.size() / count];
      depths[k] = reader.load(index, /*with_colour=*/false).depth_m;
      if (depths[k].empty()) throw InputError(reader.frameFiles(index).depth_path, 0, "cannot read the depth");
    });
    run_options.measured_noise_m = measureDepthNoise(depths, options.clusters);
    total.measured_noise_m = run_options.measured_noise_m;
  }

  // Every frame's mask, relabelled when it has a final pose.
  std::vector<HindsightMaskResult> partial(static_cast<std::size_t>(num_threads));
  std::vector<std::unique_ptr<HindsightRelabeller>> relabellers;
  std::vector<std::unique_ptr<HindsightRejudger>> rejudgers;
  for (int worker = 0; worker < num_threads; ++worker) {
    relabellers.push_back(std::make_unique<HindsightRelabeller>(camera, run_options));
    if (rejudging) rejudgers.push_back(std::make_unique<HindsightRejudger>(camera, undistorter, options.rejudge));
  }
  forEachFrame(frames.size(), num_threads, [&](int worker, std::size_t n) {
    HindsightMaskResult& mine = partial[static_cast<std::size_t>(worker)];
    const io::FrameFiles& files = reader.frameFiles(frames[n]);
    cv::Mat mask;
    if (frame_poses[n] != nullptr) {
      io::RgbdImuFrame frame = reader.load(frames[n], /*with_colour=*/false);
      mask = frame.mask;
      if (mask.empty()) throw InputError(files.mask_path, 0, "cannot read the online mask");
      if (rejudging && n > 0 && frame_poses[n - 1] != nullptr && frames[n - 1] == frames[n] - 1) {
        // The gate asks the reference frame; without one (the run's first baseline, or a baseline of
        // 0), the previous frame.
        const int gate_frame = reference_of[n] >= 0 ? reference_of[n] : static_cast<int>(n) - 1;
        const double shift_px = rejudgers[static_cast<std::size_t>(worker)]->onlineShiftPx(
            frame.depth_m, rejudge_poses[n], rejudge_poses[static_cast<std::size_t>(gate_frame)]);
        if (shift_px > options.rejudge.min_shift_px) {
          const auto rejudge_start = std::chrono::steady_clock::now();
          const int ref = reference_of[n];
          const bool with_reference = ref >= 0 && frame_poses[static_cast<std::size_t>(ref)] != nullptr;
          const auto load = [&reader](int index) { return reader.load(index); };
          if (rejudgers[static_cast<std::size_t>(worker)]->rejudge(
                  frames[n], *frame_poses[n], frames[n - 1], *frame_poses[n - 1],
                  with_reference ? frames[static_cast<std::size_t>(ref)] : -1,
                  with_reference ? *frame_poses[static_cast<std::size_t>(ref)] : SE3(), load, &mask)) {
            ++mine.frames_rejudged;
          }
          mine.rejudge_seconds +=
              std::chrono::duration<double>(std::chrono::steady_clock::now() - rejudge_start).count();
        }
      }
      const HindsightFrameResult result =
          relabellers[static_cast<std::size_t>(worker)]->relabel(frame.depth_m, *frame_poses[n], points, &mask, views,
                                                                 files.t_s);
      ++mine.frames_relabelled;
      mine.frames_changed += result.regions_flipped + result.regions_to_static > 0;
      mine.regions_flipped += result.regions_flipped;
      mine.regions_to_static += result.regions_to_static;
      mine.regions_free_space += result.regions_free_space;
      mine.views_asked += result.views_asked;
      mine.regions_voted += result.regions_voted;
    } else {
      mask = cv::imread(files.mask_path, cv::IMREAD_UNCHANGED);
      if (mask.empty()) throw InputError(files.mask_path, 0, "cannot read the online mask");
    }
    const std::string path = (fs::path(out_dir) / fs::path(files.mask_path).filename()).string();
    if (!cv::imwrite(path, mask)) throw InputError(path, 0, "cannot write the hindsight mask");
    ++mine.frames_written;
  }, kFramesPerChunk);
  for (const HindsightMaskResult& mine : partial) {
    total.frames_written += mine.frames_written;
    total.frames_relabelled += mine.frames_relabelled;
    total.frames_changed += mine.frames_changed;
    total.regions_flipped += mine.regions_flipped;
    total.regions_to_static += mine.regions_to_static;
    total.regions_free_space += mine.regions_free_space;
    total.views_asked += mine.views_asked;
    total.regions_voted += mine.regions_voted;
    total.frames_rejudged += mine.frames_rejudged;
    total.rejudge_seconds += mine.rejudge_seconds;
  }
  total.voting_points = std::count_if(points.begin(), points.end(),
                                      [&](const MapPointRecord& point) { return point.beta >= options.min_beta; });
  total.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return total;
}

}  // namespace ltlo::system
