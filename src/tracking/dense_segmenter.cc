#include "ltlo/tracking/dense_segmenter.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/map/binary_io.h"
#include "ltlo/tracking/prepared_frame.h"
#include "segmentation_worker.h"

namespace ltlo::tracking {

namespace {

/// Without any motion information (kNone) the relative pose gets a weak prior at the prediction
/// (the held pose): about a walking person's motion in one frame, so the images decide.
constexpr double kNoMotionSigmaRad = 0.2;
constexpr double kNoMotionSigmaM = 0.2;
/// Frame interval assumed when the prior has none, s.
constexpr double kDefaultDtS = 1.0 / 30.0;
/// Kept frames (Dense.ReferenceBaseline): at most this many (one every half baseline: the newest
/// at least a baseline old is the third newest at most).
constexpr std::size_t kMaxKeptFrames = 4;
/// A world correction of the previous pose beyond these (a loop closure or a merge, not local
/// mapping's millimetres) clears the kept frames: their poses would be in another world.
constexpr double kReferenceJumpM = 0.02;
constexpr double kReferenceJumpRad = 0.5 * M_PI / 180.0;
/// Frame times that jitter around a multiple of the half baseline still keep every frame and find
/// the frame one baseline back, s.
constexpr double kKeptTimeToleranceS = 1e-3;

Mat6 poseInformation(const Mat3& rotation_covariance, double translation_sigma_m) {
  Mat6 information = Mat6::Zero();
  information.block<3, 3>(0, 0) = rotation_covariance.inverse();
  information.block<3, 3>(3, 3) = Mat3::Identity() / (translation_sigma_m * translation_sigma_m);
  return information;
}

}  // namespace

segmentation::DensePrior densePrior(const MotionPrior& prior, const DenseOptions& dense) {
  segmentation::DensePrior out;
  out.T_w_b_prev = prior.T_w_b_prev;
  out.v_w_b_prev = prior.v_w_b_prev;
  out.bias_prev = prior.bias_prev;
  out.T_w_b_pred = prior.T_w_b_pred;
  out.v_w_b_pred = prior.v_w_b_pred;
  out.T_b_c = prior.T_b_c;
  out.g_w = prior.g_w;
  out.prev_velocity_sigma_m_s = dense.prior_velocity_sigma_m_s;
  const double dt_s = prior.dt_s > 0.0 ? prior.dt_s : kDefaultDtS;
  const double translation_sigma_m = dense.prior_velocity_sigma_m_s * dt_s;
  switch (prior.kind) {
    case MotionPrior::Kind::kImu: {
      LTLO_ASSERT(prior.pim != nullptr, "an IMU motion prior without preintegration");
      out.kind = segmentation::DensePrior::Kind::kImu;
      out.pim = prior.pim.get();
      // The previous state as the preintegration sees it from the prediction: the tracker may have
      // predicted from a keyframe that local mapping moved since the previous frame was tracked,
      // and the previous frame's pose must then move with it, or the image term would compare the
      // two images under the map correction instead of the motion (imu::predict inverted).
      const imu::ImuBias& bias = prior.bias_prev;
      const double dt = prior.pim->dt_s();
      const Mat3 R_prev =
          normalizeRotation(prior.T_w_b_pred.rotationMatrix() * prior.pim->correctedDeltaR(bias).transpose());
      out.v_w_b_prev = prior.v_w_b_pred - prior.g_w * dt - R_prev * prior.pim->correctedDeltaV(bias);
      const Vec3 p_prev = prior.T_w_b_pred.translation() - out.v_w_b_prev * dt - 0.5 * prior.g_w * dt * dt -
                          R_prev * prior.pim->correctedDeltaP(bias);
      out.T_w_b_prev = SE3(R_prev, p_prev);
      break;
    }
    case MotionPrior::Kind::kGyroConstantVelocity: {
      LTLO_ASSERT(prior.pim != nullptr, "a gyroscope motion prior without preintegration");
      // Rotation from the gyroscope, camera position from the constant-velocity prediction.
      const Mat3 R_w_b = normalizeRotation(prior.T_w_b_prev.rotationMatrix() * prior.pim->correctedDeltaR(prior.bias_prev));
      const Vec3 t_w_c = (prior.T_w_b_pred * prior.T_b_c).translation();
      out.T_w_b_pred = SE3(R_w_b, t_w_c - R_w_b * prior.T_b_c.translation());
      const double bias_sigma_rad = dense.prior_gyro_bias_sigma_rad_s * prior.pim->dt_s();
      const Mat3 rotation_covariance =
          prior.pim->covariance().block<3, 3>(0, 0) + bias_sigma_rad * bias_sigma_rad * Mat3::Identity();
      out.pose_information = poseInformation(rotation_covariance, translation_sigma_m);
      break;
    }
    case MotionPrior::Kind::kConstantVelocity: {
      const double rotation_sigma_rad = dense.prior_angular_rate_sigma_rad_s * dt_s;
      out.pose_information =
          poseInformation(rotation_sigma_rad * rotation_sigma_rad * Mat3::Identity(), translation_sigma_m);
      break;
    }
    case MotionPrior::Kind::kNone:
      out.pose_information =
          poseInformation(kNoMotionSigmaRad * kNoMotionSigmaRad * Mat3::Identity(), kNoMotionSigmaM);
      break;
  }
  return out;
}

DenseSegmenter::DenseSegmenter(const SegmentationOptions& segmentation, const DenseOptions& dense,
                               const LocalMappingOptions& local_mapping, const PinholeCamera& camera,
                               TimingStats* timing, std::shared_ptr<const Undistorter> undistorter)
    : segmentation_(segmentation),
      dense_(dense),
      camera_(camera),
      timing_(timing),
      undistorter_(std::move(undistorter)),
      solver_(segmentation::DenseSolverOptions::from(segmentation, dense, local_mapping)) {
  for (std::unique_ptr<PreparedFrame>& frame : frames_) frame = std::make_unique<PreparedFrame>();
  const segmentation::DenseFrameOptions frame_options = segmentation::DenseFrameOptions::from(segmentation, dense);
  auto kmeans = std::make_shared<segmentation::DepthKMeans>(segmentation::DepthKMeansOptions::from(segmentation));
  worker_ = std::make_unique<SegmentationWorker>([this, frame_options, kmeans](const io::RgbdImuFrame& input) {
    // Worker thread: writes only frames_[current_] (the tracking thread reads it after wait()).
    prepareFrame(input, camera_, frame_options, *kmeans, frames_[current_].get(), timing_, undistorter_.get());
  });
}

DenseSegmenter::~DenseSegmenter() { worker_.reset(); }

void DenseSegmenter::begin(const io::RgbdImuFrame& input) {
  LTLO_ASSERT(worker_ != nullptr, "DenseSegmenter::begin after finish()");
  worker_->post(input);
}

void DenseSegmenter::finish() {
  if (worker_ == nullptr) return;
  cancel();
  worker_.reset();
}

void DenseSegmenter::cancel() {
  if (worker_ == nullptr) return;  // finished
  try {
    worker_->wait();
  } catch (const std::exception& e) {
    log::warn("segmentation of a cancelled frame failed: ", e.what());
  }
}

SegmentationOutcome DenseSegmenter::segment(map::Frame& frame, const MotionPrior& prior) {
  LTLO_ASSERT(worker_->pending(), "DenseSegmenter::segment without begin()");
  LTLO_ASSERT(!previous_pending_, "DenseSegmenter::segment of a resumed run before restorePreviousFrame()");
  worker_->wait();
  const PreparedFrame& current = *frames_[current_];
  const PreparedFrame& previous = *frames_[1 - current_];
  SegmentationOutcome outcome;
  if (!current.valid) {
    frame.setSegmentation(map::ClusterSegmentation::allStatic(), segmentation_.static_threshold);
    has_previous_ = false;
    clearKeptFrames();
    return outcome;
  }
  const int K = current.clusters.num_clusters;
  std::vector<double> gamma(static_cast<std::size_t>(K) + 1, 1.0);
  last_result_ = segmentation::DenseResult();
  if (has_previous_ && K > 0) {
    std::optional<ScopedTimer> wall;
    std::optional<ScopedThreadCpuTimer> cpu;
    if (timing_ != nullptr) {
      wall.emplace(*timing_, "tracking.dense");
      cpu.emplace(*timing_, "tracking.dense_cpu");
    }
    const segmentation::DensePrior dense_prior = densePrior(prior, dense_);
    updateKeptFrames(prior, dense_prior);
    const KeptFrame* kept = referenceFor(current.t_s);
    segmentation::DenseReference reference;
    if (kept != nullptr) {
      reference.frame = &kept->frame->dense;
      reference.T_w_c = kept->T_w_b * prior.T_b_c;
      reference.gain = kept->gain;
      reference.offset = kept->offset;
    }
    last_result_ = solver_.solve(previous.dense, previous_gamma_, current.dense, current.clusters.edges, dense_prior,
                                 kept != nullptr ? &reference : nullptr);
    afterSolve(prior, current.t_s);
    gamma = last_result_.gamma;
    if (last_result_.state_refined) {
      outcome.state_refined = true;
      outcome.T_w_b = last_result_.T_w_b;
      outcome.v_w_b = last_result_.v_w_b;
      outcome.bias = last_result_.bias;
    }
  }
  map::ClusterSegmentation seg = clusterSegmentation(current, gamma);
  outcome.dynamic_share = 1.0 - seg.staticAreaRatio(segmentation_.static_threshold);
  if (has_previous_ && K > 0 && log::level() <= log::Level::kDebug) {  // the line's scan of gamma only when shown
    log::debug("dense t = ", current.t_s, " s: prior ", static_cast<int>(prior.kind), ", chi2 ",
               last_result_.prior_chi2, last_result_.prior_rejected ? " (rejected)" : "", ", moved ",
               (last_result_.T_w_b.translation() - prior.T_w_b_pred.translation()).norm(), " m, dynamic ",
               outcome.dynamic_share, ", gamma min ", *std::min_element(gamma.begin() + 1, gamma.end()), ", ",
               last_result_.gauss_newton_steps, " GN steps, brightness gain ", last_result_.brightness_gain,
               " offset ", last_result_.brightness_offset, referenceSummary());
  }
  frame.setSegmentation(std::move(seg), segmentation_.static_threshold);
  previous_gamma_ = std::move(gamma);
  previous_t_s_ = current.t_s;
  has_previous_ = true;
  current_ = 1 - current_;
  return outcome;
}

void DenseSegmenter::clearKeptFrames() {
  for (KeptFrame& kept : kept_) spare_frames_.push_back(std::move(kept.frame));
  kept_.clear();
  keep_previous_ = false;
}

void DenseSegmenter::updateKeptFrames(const MotionPrior& prior, const segmentation::DensePrior& dense_prior) {
  if (!(dense_.reference_baseline_s > 0.0) || prior.kind != MotionPrior::Kind::kImu) {
    clearKeptFrames();
    return;
  }
  // The world correction the IMU prior applied to the previous pose (densePrior: the previous state
  // as the preintegration sees it from the prediction).
  const SE3 correction = dense_prior.T_w_b_prev * prior.T_w_b_prev.inverse();
  if (correction.translation().norm() > kReferenceJumpM || Eigen::AngleAxisd(correction.quaternion()).angle() > kReferenceJumpRad) {
    clearKeptFrames();
    return;
  }
  for (KeptFrame& kept : kept_) kept.T_w_b = correction * kept.T_w_b;
  if (!keep_previous_) return;
  keep_previous_ = false;
  // The previous frame moves into the ring (the solve still reads it there); a spare takes its slot.
  KeptFrame kept;
  kept.frame = std::move(frames_[1 - current_]);
  kept.T_w_b = dense_prior.T_w_b_prev;
  if (spare_frames_.empty()) {
    frames_[1 - current_] = std::make_unique<PreparedFrame>();  // the ring's first rounds only
  } else {
    frames_[1 - current_] = std::move(spare_frames_.back());
    spare_frames_.pop_back();
  }
  kept_.push_back(std::move(kept));
  if (kept_.size() > kMaxKeptFrames) {
    spare_frames_.push_back(std::move(kept_.front().frame));
    kept_.erase(kept_.begin());
  }
}

void DenseSegmenter::afterSolve(const MotionPrior& prior, double t_s) {
  if (!(dense_.reference_baseline_s > 0.0) || prior.kind != MotionPrior::Kind::kImu) return;
  // I_kept ~ g I_prev + o and I_prev ~ a I_cur + b: I_kept ~ g a I_cur + (g b + o).
  for (KeptFrame& kept : kept_) {
    kept.offset += kept.gain * last_result_.brightness_offset;
    kept.gain *= last_result_.brightness_gain;
  }
  const double newest_t_s = kept_.empty() ? -std::numeric_limits<double>::infinity() : kept_.back().frame->t_s;
  keep_previous_ = t_s - newest_t_s >= 0.5 * dense_.reference_baseline_s - kKeptTimeToleranceS;
}

std::string DenseSegmenter::referenceSummary() const {
  const std::vector<double>& ref = last_result_.reference_coefficient;
  if (ref.empty()) return "";
  const std::vector<double>& data = last_result_.data_coefficient;
  int raised = 0;
  for (std::size_t k = 0; k + 1 < ref.size(); ++k) raised += ref[k] > 0.0 && ref[k] >= data[k] && data[k] > 0.0;
  std::string out = std::string(", reference") + (last_result_.reference_used ? "" : " (not used)") + ": " +
                    std::to_string(raised) + " clusters dynamic by it [";
  for (std::size_t k = 0; k + 1 < ref.size(); ++k) out += " " + std::to_string(static_cast<int>(ref[k] * 100));
  return out + " ]";
}

const DenseSegmenter::KeptFrame* DenseSegmenter::referenceFor(double t_s) const {
  for (auto it = kept_.rbegin(); it != kept_.rend(); ++it) {
    if (t_s - it->frame->t_s >= dense_.reference_baseline_s - kKeptTimeToleranceS) return &*it;
  }
  return nullptr;
}

void DenseSegmenter::writeState(map::ByteWriter& out) const {
  out.boolean(has_previous_);
  if (has_previous_) {
    out.f64(previous_t_s_);
    out.u64(previous_gamma_.size());
    for (const double g : previous_gamma_) out.f64(g);
  }
  // The kept frames (Dense.ReferenceBaseline): their images are rebuilt as the previous frame's.
  out.u64(kept_.size());
  for (const KeptFrame& kept : kept_) {
    out.f64(kept.frame->t_s);
    out.se3(kept.T_w_b);
    out.f64(kept.gain);
    out.f64(kept.offset);
  }
  out.boolean(keep_previous_);
}

void DenseSegmenter::readState(map::ByteReader& in) {
  clearKeptFrames();
  pending_kept_.clear();
  has_previous_ = in.boolean("segmenter has a previous frame");
  previous_gamma_.clear();
  previous_pending_.reset();
  if (has_previous_) {
    previous_t_s_ = in.finiteF64("segmenter's previous frame time");
    const std::uint64_t offset = in.fileOffset();
    const std::size_t n = in.count("segmenter's previous scores", 8);
    if (n < 1 || n > static_cast<std::size_t>(segmentation::kMaxClusters) + 1) {
      in.failAt(offset, "segmenter's previous scores out of [1, " + std::to_string(segmentation::kMaxClusters + 1) + "]",
                std::to_string(n));
    }
    previous_gamma_.resize(n);
    for (double& g : previous_gamma_) g = in.f64InRange("segmenter's previous score", 0.0, 1.0);
    previous_pending_ = previous_t_s_;
  }
  const std::uint64_t kept_offset = in.fileOffset();
  const std::size_t num_kept = in.count("segmenter's kept frames", 8 + 56 + 16);
  if (num_kept > (has_previous_ ? kMaxKeptFrames : 0)) {
    in.failAt(kept_offset,
              "segmenter's kept frames out of [0, " + std::to_string(has_previous_ ? kMaxKeptFrames : 0) + "]",
              std::to_string(num_kept));
  }
  double last_t_s = -std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < num_kept; ++k) {
    PendingKept kept;
    const std::uint64_t t_offset = in.fileOffset();
    kept.t_s = in.finiteF64("kept frame time");
    if (!(kept.t_s > last_t_s) || !(kept.t_s < previous_t_s_)) {
      in.failAt(t_offset, "kept frame time not after the one before it and before the previous frame's",
                map::exactNumberText(kept.t_s));
    }
    last_t_s = kept.t_s;
    kept.T_w_b = in.se3("kept frame pose");
    kept.gain = in.f64InRange("kept frame brightness gain", 0.0, 1e6);
    kept.offset = in.f64InRange("kept frame brightness offset", -1e6, 1e6);
    pending_kept_.push_back(kept);
  }
  keep_previous_ = in.boolean("segmenter keeps the previous frame");
}

std::vector<double> DenseSegmenter::keptFrameTimes() const {
  std::vector<double> times;
  for (std::size_t k = kept_.size(); k < pending_kept_.size(); ++k) times.push_back(pending_kept_[k].t_s);
  return times;
}

void DenseSegmenter::restoreKeptFrame(const io::RgbdImuFrame& frame) {
  LTLO_ASSERT(kept_.size() < pending_kept_.size(), "DenseSegmenter::restoreKeptFrame without a kept frame to restore");
  const PendingKept& pending = pending_kept_[kept_.size()];
  if (frame.t_s != pending.t_s) {
    throw InputError(frame.color_path, 0,
                     "the saved run's kept frame " + std::to_string(kept_.size()) + " is at t = " +
                         map::exactNumberText(pending.t_s) + " s, this frame at " + map::exactNumberText(frame.t_s) + " s");
  }
  // Prepared in the working slot, then moved into the ring as updateKeptFrames would have.
  worker_->post(frame);
  worker_->wait();
  if (!frames_[current_]->valid) {
    throw InputError(frame.color_path, 0, "the saved run's kept frame at t = " + map::exactNumberText(pending.t_s) +
                                              " s has no colour or depth image here");
  }
  KeptFrame kept;
  kept.frame = std::move(frames_[current_]);
  kept.T_w_b = pending.T_w_b;
  kept.gain = pending.gain;
  kept.offset = pending.offset;
  kept_.push_back(std::move(kept));
  frames_[current_] = std::make_unique<PreparedFrame>();
}

void DenseSegmenter::restorePreviousFrame(const io::RgbdImuFrame& previous) {
  LTLO_ASSERT(previous_pending_.has_value(), "DenseSegmenter::restorePreviousFrame without a previous frame to restore");
  LTLO_ASSERT(kept_.size() == pending_kept_.size(), "DenseSegmenter::restorePreviousFrame before its kept frames");
  if (previous.t_s != *previous_pending_) {
    throw InputError(previous.color_path, 0,
                     "the frame before the resumed one is at t = " + map::exactNumberText(previous.t_s) +
                         " s, the saved run's at " + map::exactNumberText(*previous_pending_) + " s");
  }
  // Prepared as begin() would have: into the slot segment() then leaves as the previous one.
  worker_->post(previous);
  worker_->wait();
  const PreparedFrame& prepared = *frames_[current_];
  if (!prepared.valid || static_cast<std::size_t>(prepared.clusters.num_clusters) + 1 != previous_gamma_.size()) {
    throw InputError(previous.color_path, 0,
                     "the frame before the resumed one gives " + std::to_string(prepared.clusters.num_clusters) +
                         " clusters, the saved run's scores are for " + std::to_string(previous_gamma_.size() - 1));
  }
  current_ = 1 - current_;
  previous_pending_.reset();
  pending_kept_.clear();
}

}  // namespace ltlo::tracking
