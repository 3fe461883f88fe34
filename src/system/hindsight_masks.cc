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
#include <thread>

#include <opencv2/imgcodecs.hpp>

#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"

namespace ltlo::system {

namespace {

constexpr char kToDynamic = 1, kToStatic = 2;  // flip_ values

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
                                                  const std::vector<MapPointRecord>& points, cv::Mat* mask) {
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
    const Vec2 u = camera_.project(p_c);
    const int ui = static_cast<int>(std::lround(u.x())), vi = static_cast<int>(std::lround(u.y()));
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
  for (int k = 0; k < R; ++k) {
    if (votes_[k] < options_.min_points || beta_sum_[k] <= 0.0) continue;
    ++result.regions_voted;
    const bool online_static = 2 * dynamic_pixels_[k] < pixels_[k];
    const double gamma_prior = 1.0 - vote_sum_[k] / beta_sum_[k];  // Eq. 56
    if (online_static && gamma_prior < options_.static_threshold) {
      flip_[k] = kToDynamic;
      ++result.regions_flipped;
    }
    if (options_.to_static && !online_static && gamma_prior >= options_.static_share) {
      flip_[k] = kToStatic;
      ++result.regions_to_static;
    }
  }
  if (result.regions_flipped == 0 && result.regions_to_static == 0) return result;
  // In a flipped region, the pixels whose nearest voter (3-D) lies within vote_radius_m and votes the
  // region's new label: the votes speak for the surface around them, not for a far end of the region (a
  // box's side face and the floor it stands on are one depth-continuous region).
  const double radius_sq = options_.vote_radius_m * options_.vote_radius_m;
  for (int r = 0; r < regions_.rows; ++r) {
    const int* regions = regions_.ptr<int>(r);
    for (int c = 0; c < regions_.cols; ++c) {
      if (regions[c] < 0 || !flip_[regions[c]]) continue;
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
      for (int dv = 0; dv < scale_; ++dv) {
        std::uint8_t* out = mask->ptr<std::uint8_t>(r * scale_ + dv) + c * scale_;
        std::fill(out, out + scale_, static_cast<std::uint8_t>(to_static ? 0 : 255));
      }
    }
  }
  return result;
}

namespace {

/// Runs fn(worker, frame position) for every position of `frames` on num_threads threads (worker 0 is
/// the caller), each thread taking every num_threads-th frame. The first exception stops the others
/// at their next frame and is rethrown after all have joined.
template <typename Fn>
void forEachFrame(std::size_t num_frames, int num_threads, Fn&& fn) {
  std::atomic<bool> failed{false};
  std::exception_ptr first_error;
  std::mutex error_mutex;  // guards first_error
  auto work = [&](int worker) {
    try {
      for (std::size_t n = static_cast<std::size_t>(worker); n < num_frames && !failed.load();
           n += static_cast<std::size_t>(num_threads)) {
        fn(worker, n);
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
                                        map::MapId points_map, const std::vector<MapPointRecord>& points,
                                        const CameraModel& camera, const HindsightMaskOptions& options,
                                        const std::string& out_dir) {
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

  // Every frame's mask, relabelled when it has a final pose.
  std::vector<HindsightMaskResult> partial(static_cast<std::size_t>(num_threads));
  std::vector<std::unique_ptr<HindsightRelabeller>> relabellers;
  for (int worker = 0; worker < num_threads; ++worker) {
    relabellers.push_back(std::make_unique<HindsightRelabeller>(camera, options));
  }
  forEachFrame(frames.size(), num_threads, [&](int worker, std::size_t n) {
    HindsightMaskResult& mine = partial[static_cast<std::size_t>(worker)];
    const io::FrameFiles& files = reader.frameFiles(frames[n]);
    cv::Mat mask;
    if (frame_poses[n] != nullptr) {
      io::RgbdImuFrame frame = reader.load(frames[n], /*with_colour=*/false);
      mask = frame.mask;
      if (mask.empty()) throw InputError(files.mask_path, 0, "cannot read the online mask");
      const HindsightFrameResult result =
          relabellers[static_cast<std::size_t>(worker)]->relabel(frame.depth_m, *frame_poses[n], points, &mask);
      ++mine.frames_relabelled;
      mine.frames_changed += result.regions_flipped + result.regions_to_static > 0;
      mine.regions_flipped += result.regions_flipped;
      mine.regions_to_static += result.regions_to_static;
      mine.regions_voted += result.regions_voted;
    } else {
      mask = cv::imread(files.mask_path, cv::IMREAD_UNCHANGED);
      if (mask.empty()) throw InputError(files.mask_path, 0, "cannot read the online mask");
    }
    const std::string path = (fs::path(out_dir) / fs::path(files.mask_path).filename()).string();
    if (!cv::imwrite(path, mask)) throw InputError(path, 0, "cannot write the hindsight mask");
    ++mine.frames_written;
  });
  for (const HindsightMaskResult& mine : partial) {
    total.frames_written += mine.frames_written;
    total.frames_relabelled += mine.frames_relabelled;
    total.frames_changed += mine.frames_changed;
    total.regions_flipped += mine.regions_flipped;
    total.regions_to_static += mine.regions_to_static;
    total.regions_voted += mine.regions_voted;
  }
  total.voting_points = std::count_if(points.begin(), points.end(),
                                      [&](const MapPointRecord& point) { return point.beta >= options.min_beta; });
  total.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return total;
}

}  // namespace ltlo::system
