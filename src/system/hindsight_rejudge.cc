#include "ltlo/system/hindsight_rejudge.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "ltlo/core/assert.h"

namespace ltlo::system {

RejudgeOptions RejudgeOptions::from(const Settings& settings) {
  RejudgeOptions options;
  options.enable = settings.segmentation.hindsight_rejudge;
  options.min_shift_px = settings.segmentation.hindsight_rejudge_min_shift_px;
  options.reference_baseline_s = settings.dense.reference_baseline_s;
  options.static_threshold = settings.segmentation.static_threshold;
  options.frame = segmentation::DenseFrameOptions::from(settings.segmentation, settings.dense);
  options.solver =
      segmentation::DenseSolverOptions::from(settings.segmentation, settings.dense, settings.local_mapping);
  options.clusters = segmentation::DepthKMeansOptions::from(settings.segmentation);
  return options;
}

HindsightRejudger::HindsightRejudger(const CameraModel& camera, std::shared_ptr<const Undistorter> undistorter,
                                     const RejudgeOptions& options)
    : camera_(camera),
      undistorter_(std::move(undistorter)),
      options_(options),
      solver_(options.solver),
      kmeans_(options.clusters),
      raw_grid_(undistorter_) {
  const int width = camera.pinhole().width();
  LTLO_ASSERT(options.frame.width > 0 && width % options.frame.width == 0,
              "label width " << options.frame.width << " for a camera " << width << " px wide");
  label_scale_ = width / options.frame.width;
  label_camera_ = camera.pinhole().scaled(1.0 / label_scale_);
  // Bearings (z = 1, lens included) of the gate's grid on the raw image.
  for (int v = kGateStride / 2; v < camera.pinhole().height(); v += kGateStride) {
    for (int u = kGateStride / 2; u < width; u += kGateStride) {
      const std::optional<Vec3> ray = camera.unproject(Vec2(u, v));
      gate_pixels_.push_back({u, v});
      gate_bearings_.push_back(ray ? Vec3(*ray / ray->z()) : Vec3::Zero());
    }
  }
}

double HindsightRejudger::onlineShiftPx(const cv::Mat& depth_m, const RejudgePoses& current,
                                        const RejudgePoses& reference) const {
  if (current.T_w_c_final == nullptr || current.T_w_c_online == nullptr || reference.T_w_c_final == nullptr ||
      reference.T_w_c_online == nullptr || depth_m.empty()) {
    return -1.0;
  }
  if (current.online_map != reference.online_map) return std::numeric_limits<double>::infinity();
  // The frame's surface in the reference camera under each relative pose, T_ref_cur.
  const SE3 final_ref_cur = reference.T_w_c_final->inverse() * *current.T_w_c_final;
  const SE3 online_ref_cur = reference.T_w_c_online->inverse() * *current.T_w_c_online;
  const Mat3 R_f = final_ref_cur.rotationMatrix(), R_o = online_ref_cur.rotationMatrix();
  const Vec3 t_f = final_ref_cur.translation(), t_o = online_ref_cur.translation();
  double sum = 0.0;
  int count = 0;
  for (std::size_t k = 0; k < gate_pixels_.size(); ++k) {
    if (gate_bearings_[k].z() <= 0.0) continue;
    const float z = depth_m.ptr<float>(gate_pixels_[k].second)[gate_pixels_[k].first];
    if (!(z > 0.0f) || !std::isfinite(z)) continue;
    const Vec3 x_c = gate_bearings_[k] * static_cast<double>(z);
    const Vec3 a = R_f * x_c + t_f, b = R_o * x_c + t_o;
    if (a.z() <= 0.05 || b.z() <= 0.05) continue;
    sum += (label_camera_.project(a) - label_camera_.project(b)).norm();
    ++count;
  }
  return count > 0 ? sum / count : -1.0;
}

std::vector<double> HindsightRejudger::staticShares(const tracking::PreparedFrame& prepared, const cv::Mat& mask) {
  const int K = prepared.clusters.num_clusters;
  std::vector<double> gamma(static_cast<std::size_t>(K) + 1, 1.0);
  if (mask.empty()) return gamma;
  // The online mask on the ideal grid, then read at each label pixel's centre.
  const cv::Mat* ideal = &mask;
  if (undistorter_ && undistorter_->active()) {
    undistorter_->toIdeal(mask, &mask_ideal_, cv::INTER_NEAREST);
    ideal = &mask_ideal_;
  }
  std::vector<int> pixels(static_cast<std::size_t>(K), 0), still(static_cast<std::size_t>(K), 0);
  const cv::Mat& labels = prepared.clusters.labels;
  const int scale = prepared.dense.scale();
  for (int r = 0; r < labels.rows; ++r) {
    const std::uint8_t* label = labels.ptr<std::uint8_t>(r);
    const std::uint8_t* online = ideal->ptr<std::uint8_t>(std::min(ideal->rows - 1, r * scale + scale / 2));
    for (int c = 0; c < labels.cols; ++c) {
      if (label[c] >= K) continue;
      ++pixels[label[c]];
      still[label[c]] += online[std::min(ideal->cols - 1, c * scale + scale / 2)] < 128;
    }
  }
  for (int k = 0; k < K; ++k) {
    if (pixels[static_cast<std::size_t>(k)] > 0) {
      gamma[static_cast<std::size_t>(k)] =
          static_cast<double>(still[static_cast<std::size_t>(k)]) / pixels[static_cast<std::size_t>(k)];
    }
  }
  return gamma;
}

const HindsightRejudger::CachedFrame& HindsightRejudger::prepared(int index, const FrameLoader& load) {
  for (std::size_t k = 0; k < cache_.size(); ++k) {
    if (cache_[k]->index != index) continue;
    const auto entry = cache_.begin() + static_cast<std::ptrdiff_t>(k);
    std::rotate(cache_.begin(), entry, entry + 1);  // to the front
    return *cache_.front();
  }
  if (cache_.size() < kCachedFrames) {
    cache_.insert(cache_.begin(), std::make_unique<CachedFrame>());
  } else {
    std::rotate(cache_.begin(), cache_.end() - 1, cache_.end());  // the least recently used, reused
  }
  CachedFrame& entry = *cache_.front();
  entry.index = index;
  const io::RgbdImuFrame frame = load(index);
  tracking::prepareFrame(frame, camera_.pinhole(), options_.frame, kmeans_, &entry.prepared, nullptr,
                         undistorter_.get());
  entry.valid = entry.prepared.valid && entry.prepared.clusters.num_clusters > 0;
  entry.static_shares = entry.valid ? staticShares(entry.prepared, frame.mask) : std::vector<double>();
  return entry;
}

bool HindsightRejudger::rejudge(int current_index, const SE3& T_w_c_current, int previous_index,
                                const SE3& T_w_c_previous, int reference_index, const SE3& T_w_c_reference,
                                const FrameLoader& load, cv::Mat* mask) {
  LTLO_ASSERT(mask != nullptr, "HindsightRejudger::rejudge without a mask");
  LTLO_ASSERT(kCachedFrames >= 3, "the cache holds the three frames of a judgement");
  // The reference first: the three entries stay in the cache until the judgement is over.
  const CachedFrame* reference = reference_index >= 0 ? &prepared(reference_index, load) : nullptr;
  const CachedFrame& previous = prepared(previous_index, load);
  const CachedFrame& current = prepared(current_index, load);
  if (!current.valid || !previous.valid) return false;
  if (reference != nullptr && !reference->valid) reference = nullptr;
  // Camera poses as body poses (T_b_c the identity): the relative-pose prior pinned at the final poses.
  const double information = 1.0 / (kPinnedSigma * kPinnedSigma);
  segmentation::DensePrior prior;
  prior.kind = segmentation::DensePrior::Kind::kRelativePose;
  prior.T_b_c = SE3();
  prior.pose_information = information * Mat6::Identity();
  segmentation::DenseReference ref;
  if (reference != nullptr) {
    // The reference's brightness relative to the previous frame: the previous frame solved against it
    // at their final poses (I_ref(W(u)) ~ gain I_prev(u) + offset).
    prior.T_w_b_prev = T_w_c_reference;
    prior.T_w_b_pred = T_w_c_previous;
    const segmentation::DenseResult fit =
        solver_.solve(reference->prepared.dense, reference->static_shares, previous.prepared.dense,
                      previous.prepared.clusters.edges, prior);
    ref.frame = &reference->prepared.dense;
    ref.T_w_c = T_w_c_reference;
    ref.gain = fit.brightness_gain;
    ref.offset = fit.brightness_offset;
  }
  prior.T_w_b_prev = T_w_c_previous;
  prior.T_w_b_pred = T_w_c_current;
  const segmentation::DenseResult result =
      solver_.solve(previous.prepared.dense, previous.static_shares, current.prepared.dense,
                    current.prepared.clusters.edges, prior, ref.frame != nullptr ? &ref : nullptr);
  const cv::Mat labels =
      tracking::clusterSegmentation(current.prepared, result.gamma).dynamicMask(options_.static_threshold);
  // The next frame of a stretch takes this judgement as its temporal prior: each cluster static as far as
  // either judgement says (the mask below keeps the online static pixels too).
  CachedFrame& judged = *cache_.front();
  LTLO_ASSERT(judged.index == current_index, "the judged frame left the front of the cache");
  for (std::size_t k = 0; k < judged.static_shares.size() && k < result.gamma.size(); ++k) {
    judged.static_shares[k] = std::max(judged.static_shares[k], result.gamma[k]);
  }
  // On the raw image's grid, as the online masks are written (SegmentationWriter).
  const cv::Mat& rejudged =
      raw_grid_.toRaw(labels, camera_.pinhole().width(), camera_.pinhole().height(), &rejudged_);
  // Only the online pass's dynamic pixels can turn static; a pixel the online motion found static stays.
  if (mask->size() == rejudged.size() && mask->type() == CV_8UC1) {
    cv::min(*mask, rejudged, *mask);
  } else {
    rejudged.copyTo(*mask);
  }
  return true;
}

}  // namespace ltlo::system
