#include "ltlo/mapping/local_mapper.h"

#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <utility>

#include "bow/vocabulary.h"
#include "imu_initializer.h"
#include "local_window_ba.h"
#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "ltlo/core/process_memory.h"
#include "ltlo/core/timing.h"
#include "ltlo/map/run_state_io.h"
#include "ltlo/optim/bundle_adjust.h"
#include "map_culling.h"
#include "point_fusion.h"
#include "time_offset_estimator.h"

namespace ltlo::mapping {

namespace {

double angleDeg(const Vec3& a, const Vec3& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

/// A keyframe's processing split by step (ms), for the mapping timeline.
struct MappingPhaseTimes {
  double points_ms = 0.0;
  double ba_ms = 0.0;
  double keyframe_culling_ms = 0.0;
  double imu_ms = 0.0;
};

}  // namespace

struct LocalMapper::Impl {
  Impl(map::Atlas& atlas_in, const LocalMapperOptions& options_in, std::vector<float> level_sigma2_in,
       TimingStats* timing_in)
      : atlas(atlas_in),
        options(options_in),
        level_sigma2(std::move(level_sigma2_in)),
        timing(timing_in),
        queue(options_in.queue_capacity),
        recent_points(recentOptions(options_in)) {}

  static RecentPointCuller::Options recentOptions(const LocalMapperOptions& options) {
    RecentPointCuller::Options recent;
    recent.min_point_beta = options.local_mapping.min_point_beta;
    return recent;
  }

  void process(const std::shared_ptr<map::KeyFrame>& kf, bool threaded);
  /// Appends `kf`'s entry to the mapping timeline (atlas sizes and memory read now) with its local
  /// BA's problem size `ba`.
  void recordTimeline(const map::KeyFrame& kf, double mapping_ms, double mapping_cpu_ms, const WindowBaStats& ba,
                      const MappingPhaseTimes& phases);
  WindowBaStats localBundleAdjust(map::Map& map, const std::shared_ptr<map::KeyFrame>& kf, const ImuState& imu,
                         bool threaded, LocalMapperCounters& delta);
  /// Initialises or refines the IMU estimate when due; true when it did.
  bool maybeInitialiseImu(map::Map& map, const std::shared_ptr<map::KeyFrame>& kf);
  void publishImu(const ImuInitEstimate& estimate, const char* what, bool awaiting_own_initialisation = false);
  /// After an IMU estimate: one warning when the chain's inertial residuals are far beyond the
  /// noise model (the calibration is then inconsistent with the data).
  void checkImuConsistency(const ImuChain& chain, const Vec3& g_w);
  /// Re-estimates the camera-IMU shift on `kf`'s chain and moves the map's IMU boundaries to it.
  void updateTimeOffset(map::Map& map, const map::KeyFrame& kf, const ImuState& imu);

  map::Atlas& atlas;
  const LocalMapperOptions options;
  const std::vector<float> level_sigma2;
  TimingStats* const timing;

  BlockingQueue<std::shared_ptr<map::KeyFrame>> queue;
  /// Raised by insertKeyFrame() and pause(): the running BA stops at its next iteration.
  std::atomic<bool> stop_ba{false};
  std::atomic<bool> finished{false};

  // Pause handshake (pause_mutex guards the three fields).
  std::mutex pause_mutex;
  std::condition_variable pause_cv;
  int pause_requests = 0;   ///< pause() calls not yet resumed
  bool processing = false;  ///< run() is inside a keyframe's processing (or about to be)
  std::atomic<bool> pause_requested{false};

  // Shared with other threads (state_mutex guards these).
  mutable std::mutex state_mutex;
  ImuState imu_state;
  LocalMapperCounters counters;
  std::vector<MappingTimelineEntry> timeline;  ///< ~20 bytes x 2 keyframes/s: 0.3 MB per hour
  TimeOffsetStatus time_offset;
  std::atomic<double> time_shift_s{0.0};  // time_offset.shift_s, for tracking's every frame
  std::function<void(const std::shared_ptr<map::KeyFrame>&)> processed_callback;

  // Mapping thread only (or the synchronous caller).
  RecentPointCuller recent_points;
  int sequence = 0;
  double first_imu_init_t_s = 0.0;
  /// Keyframe time of an initialisation from rest the full one has not followed yet (-1: none).
  double rest_init_t_s = -1.0;
  /// A first initialisation rejected for its accelerometer bias (ImuInit.MaxAccBias) ended at this
  /// keyframe time; the next one uses only later keyframes (-1: none rejected).
  double imu_chain_floor_t_s = -1.0;
  double last_imu_estimate_t_s = 0.0;  ///< keyframe time of the last (re)estimate
  double last_imu_chain_end_t_s = -1.0;  ///< newest keyframe the last applied estimate used
  std::size_t imu_refinements = 0;  ///< refinements done (index into imu_refinement_delays_s)
  double time_shift_logged_s = 0.0;   ///< the estimate last written to the log
  bool time_offset_warned = false;
  bool imu_consistency_warned = false;
};

void LocalMapper::Impl::process(const std::shared_ptr<map::KeyFrame>& kf, bool threaded) {
  LTLO_ASSERT(kf != nullptr, "LocalMapper: null keyframe");
  const auto start = std::chrono::steady_clock::now();
  const double cpu_start_s = threadCpuTimeS();
  std::optional<ScopedTimer> timer;
  if (timing != nullptr) timer.emplace(*timing, "mapping.keyframe");
  LocalMapperCounters delta;
  WindowBaStats ba_stats;
  MappingPhaseTimes phases;
  auto phase_start = start;
  // The milliseconds since the previous phase ended (the timeline's per-phase columns).
  auto end_phase = [&phase_start]() {
    const auto now = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - phase_start).count();
    phase_start = now;
    return ms;
  };
  map::Map* map = atlas.map(kf->mapId());
  if (map != nullptr && !kf->isBad()) {
    ++sequence;
    // 1. Recent map-point culling (and the dynamic points of this keyframe).
    recent_points.addPointsOf(*map, *kf, sequence);
    delta.culled_points += recent_points.cull(atlas, sequence);
    delta.culled_points += cullDynamicPoints(*map, *kf, options.local_mapping.min_point_beta);

    // 2. Duplicate fusion with the neighbours.
    FusionOptions fusion;
    fusion.bf_px_m = options.bf_px_m;
    fusion.min_point_beta = options.local_mapping.min_point_beta;
    const FusionStats fused = fuseWithNeighbours(*map, *kf, fusion, level_sigma2);
    delta.fused_points += fused.replaced + fused.linked;
    phases.points_ms = end_phase();

    // 3. Local (visual-inertial) BA, unless more keyframes wait (ORB-SLAM: they come first).
    const ImuState imu = [&] {
      std::lock_guard<std::mutex> lock(state_mutex);
      return imu_state;
    }();
    if (options.use_imu && imu.initialised) predictInertialState(*map, *kf, imu.g_w);
    stop_ba.store(pause_requested.load());
    if (map->numKeyFrames() > 1 && !(threaded && queue.size() > 0) && !stop_ba.load()) {
      ba_stats = localBundleAdjust(*map, kf, imu, threaded, delta);
      ++delta.local_ba_runs;
    }
    phases.ba_ms = end_phase();

    // 4. Keyframe culling.
    KeyFrameCullingOptions culling;
    culling.redundant_ratio = options.local_mapping.redundant_ratio;
    culling.use_imu = options.use_imu;
    if (imu.initialised) {
      culling.max_imu_span_s = options.local_mapping.cull_max_imu_span_s;
      culling.cut_imu_min_age_s = options.local_mapping.cull_imu_cut_age_s;
    }
    int cut_links = 0;
    for (const map::KeyFrameId id : cullRedundantKeyFrames(*map, *kf, culling, &cut_links)) {
      atlas.keyFrameDatabase().erase(id);
      ++delta.culled_keyframes;
    }
    if (cut_links > 0) log::debug("culling at kf ", kf->id(), ": ", cut_links, " old keyframes culled, IMU chain cut");
    phases.keyframe_culling_ms = end_phase();

    // 5. IMU initialisation and its refinements.
    if (options.use_imu && maybeInitialiseImu(*map, kf)) ++delta.imu_initialisations;

    // 6. The camera-IMU time offset on the refined rotations.
    if (options.use_imu && options.local_mapping.estimate_time_offset && !kf->isBad()) {
      updateTimeOffset(*map, *kf, imu);
    }
    phases.imu_ms = end_phase();
  }
  std::function<void(const std::shared_ptr<map::KeyFrame>&)> callback;
  {
    std::lock_guard<std::mutex> lock(state_mutex);
    ++counters.keyframes_processed;
    counters.culled_keyframes += delta.culled_keyframes;
    counters.culled_points += delta.culled_points;
    counters.dynamic_points += delta.dynamic_points;
    counters.bow_updates += delta.bow_updates;
    counters.fused_points += delta.fused_points;
    counters.local_ba_runs += delta.local_ba_runs;
    counters.imu_initialisations += delta.imu_initialisations;
    callback = processed_callback;
  }
  if (timer) timer->stop();
  recordTimeline(*kf, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count(),
                 1e3 * (threadCpuTimeS() - cpu_start_s), ba_stats, phases);
  // 6. Hand on (loop closing).
  if (callback) callback(kf);
}

void LocalMapper::Impl::updateTimeOffset(map::Map& map, const map::KeyFrame& kf, const ImuState& imu) {
  // An estimate is used once it knows the shift to this (s); the links a few seconds of turning
  // give reach ~0.3 ms, a straight or constant turn leaves the prior's 25 ms.
  constexpr double kMaxUsefulSigmaS = 0.003;
  constexpr int kMinLinks = 8;
  // Boundaries closer than this to the estimate stay (the step it moves by, at most, unseen).
  constexpr double kMinBoundaryMoveS = 2e-4;
  std::optional<ScopedTimer> timer;
  if (timing != nullptr) timer.emplace(*timing, "mapping.time_offset");
  const std::vector<TimeOffsetLink> links = chainLinks(map, kf, options.local_mapping.time_offset_window);
  if (static_cast<int>(links.size()) < kMinLinks) return;
  TimeOffsetOptions estimator;
  estimator.prior_sigma_s = options.local_mapping.time_offset_prior_sigma_s;
  const double current = time_shift_s.load();
  const Vec3 b_g = imu.initialised ? kf.bias().b_g : links.front().pim.bias().b_g;
  const std::optional<TimeOffsetEstimate> estimate = estimateTimeOffset(links, current, b_g, estimator);
  if (!estimate || estimate->sigma_s > kMaxUsefulSigmaS) return;
  const int moved = moveChainBoundaries(map, kf.id(), estimate->shift_s, kMinBoundaryMoveS);
  time_shift_s.store(estimate->shift_s);
  bool first = false;
  {
    std::lock_guard<std::mutex> lock(state_mutex);
    first = !time_offset.estimated;
    time_offset.estimated = true;
    time_offset.shift_s = estimate->shift_s;
    time_offset.sigma_s = estimate->sigma_s;
    ++time_offset.updates;
    time_offset.boundaries_moved += moved;
    if (first) time_offset.first_estimate_t_s = kf.t_s();
  }
  if (first || std::abs(estimate->shift_s - time_shift_logged_s) > 1e-3) {
    log::info("IMU time offset: ", estimate->shift_s * 1e3, " ms +- ", estimate->sigma_s * 1e3, " ms beyond IMU.TimeOffset (",
              estimate->links, " links to t = ", kf.t_s(), " s, rotation rms ", estimate->rms_rad * 1e3, " mrad, ", moved,
              " boundaries moved)");
    time_shift_logged_s = estimate->shift_s;
  } else {
    log::debug("IMU time offset: ", estimate->shift_s * 1e3, " ms +- ", estimate->sigma_s * 1e3, " ms (", estimate->links,
               " links, ", moved, " boundaries moved)");
  }
  if (!time_offset_warned && std::abs(estimate->shift_s) > 3.0 * estimator.prior_sigma_s) {
    time_offset_warned = true;
    log::warn("IMU.TimeOffset: the online estimate puts the IMU clock ", estimate->shift_s * 1e3,
              " ms from the calibration's offset, beyond 3 sigma of its prior (LocalMapping.TimeOffsetPriorSigma = ",
              estimator.prior_sigma_s * 1e3, " ms): IMU.TimeOffset is likely wrong");
  }
}

WindowBaStats LocalMapper::Impl::localBundleAdjust(map::Map& map, const std::shared_ptr<map::KeyFrame>& kf,
                                                   const ImuState& imu, bool threaded, LocalMapperCounters& delta) {
  std::optional<ScopedTimer> timer;
  if (timing != nullptr) timer.emplace(*timing, "mapping.local_ba");
  WindowBaOptions ba;
  ba.window_size = options.local_mapping.window_size;
  ba.max_fixed_keyframes = static_cast<std::size_t>(options.local_mapping.max_fixed_keyframes);
  ba.max_fixed_observations_per_point =
      static_cast<std::size_t>(options.local_mapping.max_fixed_observations_per_point);
  ba.max_fixed_observation_ratio = options.local_mapping.max_fixed_observation_ratio;
  ba.max_probe_point_ratio = options.local_mapping.max_probe_point_ratio;
  ba.iterations = options.local_mapping.ba_iterations;
  ba.bf_px_m = options.bf_px_m;
  ba.min_point_beta = options.local_mapping.min_point_beta;
  ba.num_threads = options.ba_threads;
  ba.inertial = options.use_imu && imu.initialised && kf->imuFromPrevious().has_value();
  ba.g_w = imu.g_w;
  ba.lambda_imu = options.local_mapping.lambda_imu;
  ba.gauge_velocity_free = options.local_mapping.gauge_velocity_free;
  ba.gauge_velocity_prior = options.local_mapping.gauge_velocity_prior;
  if (ba.inertial && options.imu_init.loose_early_bias && imu_refinements == 0) {
    // Before the +5 s refinement the estimate comes from the first seconds: the bias the held
    // keyframes carry is known to its acceleration sigma at best, and the fixed-pose sigma of a
    // short window is optimistic, so at least what tracking assumes (Tracking.AccBiasSigma).
    // (10 m/s^2 bounds it where the covariance is singular: no accelerometer is biased further.)
    ba.held_acc_bias_sigma_m_s2 =
        std::clamp(optim::accelerationSigma(imu.acceleration_covariance_w),
                   options.refine_until_acceleration_sigma_m_s2, 10.0);
  }
  ba.huber_chi2 = options.local_mapping.huber_chi2;
  ba.robust = options.local_mapping.robust_beta;
  ba.alternations = options.local_mapping.alternations;
  ba.evidence_only = options.local_mapping.scores_need_evidence;
  ba.scores.lambda_d = options.local_mapping.lambda_d;
  ba.scores.lambda_s = options.segmentation.lambda_s;
  ba.scores.lambda_p = options.segmentation.lambda_p;
  ba.scores.lambda_phi = options.segmentation.lambda_phi;
  ba.scores.huber_delta = std::sqrt(options.local_mapping.huber_chi2);
  ba.scores.sweeps = options.local_mapping.score_sweeps;
  ba.stop_flag = threaded ? &stop_ba : nullptr;
  const WindowBaStats stats = localWindowBundleAdjust(map, kf, ba, level_sigma2);
  delta.dynamic_points += stats.dynamic_points_erased;
  for (const std::shared_ptr<map::KeyFrame>& changed : stats.static_set_changed) {
    if (options.vocabulary == nullptr || changed->isBad()) continue;
    auto [bow_vector, feature_vector] = map::staticKeypointsBow(*changed, *options.vocabulary);
    changed->setBow(std::move(bow_vector), std::move(feature_vector));
    atlas.keyFrameDatabase().replace(changed);
    ++delta.bow_updates;
  }
  log::debug("local BA at kf ", kf->id(), (ba.inertial ? " (inertial)" : ""), (ba.robust ? " (robust)" : ""), ": ",
             stats.optimised_keyframes, " optimised + ", stats.fixed_keyframes, " fixed keyframes, ", stats.points,
             " points, ", stats.observations, " observations, ", stats.dynamic_points_erased, " dynamic points and ",
             stats.outliers_erased, " outliers erased, c^ = ", stats.c_hat, ", ", stats.static_set_changed.size(),
             " keyframes' static features changed", (stats.aborted ? ", aborted" : ""));
  return stats;
}

bool LocalMapper::Impl::maybeInitialiseImu(map::Map& map, const std::shared_ptr<map::KeyFrame>& kf) {
  const ImuState state = [&] {
    std::lock_guard<std::mutex> lock(state_mutex);
    return imu_state;
  }();
  if (!state.initialised && options.imu_init.from_rest && kf->atRest()) {
    // A still start (issue 32): gravity and the gyro bias from the standstill link.
    const std::optional<ImuInitEstimate> estimate =
        initialiseImuAtRest(imuChainEndingAt(map, kf), 0.9 * options.imu_init.rest_time_s,
                            options.refine_until_acceleration_sigma_m_s2);
    if (estimate) {
      rest_init_t_s = kf->t_s();
      first_imu_init_t_s = kf->t_s();
      last_imu_estimate_t_s = kf->t_s();
      last_imu_chain_end_t_s = kf->t_s();
      publishImu(*estimate, "initialised from rest");
      return true;
    }
    log::info("IMU initialisation from rest at kf ", kf->id(), ": the link is no standstill; waiting for motion");
  }
  // The rest before the first map (issue 32): gravity and the gyro bias known, the velocities and b_a
  // from the map's first keyframes. Only the map's first keyframe (its gauge) can carry the rest, so
  // a map without one builds no chain here.
  const std::shared_ptr<map::KeyFrame> gauge =
      !state.initialised && options.imu_init.from_pre_map_rest ? map.keyFrame(map.gaugeKeyFrame()) : nullptr;
  if (gauge && gauge->preMapRest()) {
    const ImuChain chain = endAtStaticView(imuChainEndingAt(map, kf), options.imu_init.min_static_ratio);
    const std::optional<imu::RestEstimate> rest =
        chain.keyframes.empty() ? std::nullopt : chain.keyframes.front()->preMapRest();
    if (rest && chain.keyframes.size() >= 3 && chain.span_s() >= options.imu_init.pre_map_min_time_s) {
      std::optional<ScopedTimer> timer;
      if (timing != nullptr) timer.emplace(*timing, "mapping.imu_init");
      const std::optional<ImuInitEstimate> estimate =
          initialiseImuOnChain(chain, options.imu_init, imu::ImuBias(), &*rest);
      if (estimate) {
        // The full initialisation follows once the map's own keyframes span ImuInit.MinTime from its
        // first (they move from the start, unlike a still start's).
        rest_init_t_s = chain.keyframes.front()->t_s();
        first_imu_init_t_s = chain.keyframes.back()->t_s();
        last_imu_estimate_t_s = kf->t_s();
        last_imu_chain_end_t_s = first_imu_init_t_s;
        log::info("IMU: the rest before the map: ", rest->rest_s, " s, g_w = (", rest->g_w.transpose(),
                  ") m/s^2, b_g = (", rest->b_g.transpose(), ") rad/s");
        publishImu(*estimate, "initialised from the rest before the map", true);
        checkImuConsistency(chain, estimate->g_w);
        return true;
      }
      log::warn("IMU initialisation from the rest before the map at kf ", kf->id(),
                " gave a non-finite estimate; waiting for the map's own");
    }
  }
  // After an initialisation from rest the full one follows (inertial-only, which also finds the
  // accelerometer bias rest cannot tell from gravity, then the visual-inertial BA), once
  // ImuInit.MinTime of keyframes after the rest keyframe is covered; the refinement schedule counts
  // from it. Until then the rest estimate serves tracking.
  const bool after_rest = state.initialised && rest_init_t_s >= 0.0;
  const bool initialised = state.initialised && !after_rest;
  const char* what = nullptr;
  if (!initialised) {
    what = after_rest ? "initialised (in motion, after rest)" : "initialised";
  } else if (imu_refinements < options.imu_refinement_delays_s.size() &&
             kf->t_s() - first_imu_init_t_s >= options.imu_refinement_delays_s[imu_refinements]) {
    what = "refined";
  } else if (options.imu_init.refine_interval_s > 0.0 &&
             (imu_refinements == 0 ||
              optim::accelerationSigma(state.acceleration_covariance_w) > options.refine_until_acceleration_sigma_m_s2) &&
             kf->t_s() - last_imu_estimate_t_s >= options.imu_init.refine_interval_s) {
    // Until the first scheduled refinement always: the sigma holds the keyframe poses exact, so
    // for a short window it is a lower bound (a 2.3 s window claimed 0.013 m/s^2 and bridged a
    // 1.5 s black-out 8 cm off); afterwards while it is above what tracking assumes.
    what = "refined (early window)";
  } else {
    return false;
  }
  // The estimate ends at the newest keyframe whose view is mostly static (on ltlo_s3 the window
  // that took in the second a box covered 40-90 % of the view moved gravity from 0.13-0.25 to
  // 0.40-0.50 deg off, which then integrated over the occlusion's dead reckoning).
  ImuChain chain = endAtStaticView(imuChainEndingAt(map, kf), options.imu_init.min_static_ratio);
  chain = startAfter(std::move(chain), imu_chain_floor_t_s);  // refinements too: those poses did not fit
  if (static_cast<int>(chain.keyframes.size()) < std::max(3, options.imu_init.min_keyframes) ||
      chain.span_s() < options.imu_init.min_time_s ||
      (after_rest && chain.keyframes.back()->t_s() - rest_init_t_s < options.imu_init.min_time_s)) {
    return false;
  }
  // Nothing new since the last estimate (the view has been occluded since): wait.
  if (initialised && chain.keyframes.back()->t_s() <= last_imu_chain_end_t_s) return false;
  const bool refinement = initialised && options.imu_init.visual_inertial_refinement;
  std::optional<ScopedTimer> timer;
  if (timing != nullptr) timer.emplace(*timing, refinement ? "mapping.imu_refine" : "mapping.imu_init");
  std::optional<ImuInitEstimate> current;
  if (initialised) current = ImuInitEstimate{state.g_w, state.bias};
  RefinementContext context{options.bf_px_m, options.local_mapping.min_point_beta,
                            options.local_mapping.lambda_imu,
                            options.local_mapping.visual_variance_estimation, options.ba_threads, level_sigma2};
  if (initialised) context.max_acceleration_sigma_m_s2 = optim::accelerationSigma(state.acceleration_covariance_w);
  bool implausible_bias = false;
  const std::optional<ImuInitEstimate> estimate =
      estimateImu(map, chain, options.imu_init, context, current, &implausible_bias);
  const bool scheduled = initialised && imu_refinements < options.imu_refinement_delays_s.size() &&
                         kf->t_s() - first_imu_init_t_s >= options.imu_refinement_delays_s[imu_refinements];
  if (!estimate) {
    if (!initialised && implausible_bias) {
      // ImuInit.MaxAccBias: the poses of this chain were wrong (estimateImu warned); the next
      // initialisation starts after them, once ImuInit.MinTime of new keyframes is covered.
      imu_chain_floor_t_s = chain.keyframes.back()->t_s();
      log::warn("IMU initialisation: the next one uses the keyframes after t = ", imu_chain_floor_t_s, " s");
      return false;
    }
    if (!initialised) {
      log::warn("IMU initialisation at kf ", kf->id(), " gave a non-finite estimate; retrying later");
      return false;
    }
    // A refinement that was not applied (non-finite, or less informed than the current estimate)
    // counts as done: the next one follows the schedule, not every keyframe.
    if (scheduled) ++imu_refinements;
    last_imu_estimate_t_s = kf->t_s();
    return false;
  }
  if (!initialised) {
    first_imu_init_t_s = kf->t_s();
    rest_init_t_s = -1.0;
  } else if (scheduled) {
    ++imu_refinements;
  }
  last_imu_estimate_t_s = kf->t_s();
  last_imu_chain_end_t_s = chain.keyframes.back()->t_s();
  publishImu(*estimate, what);
  checkImuConsistency(chain, estimate->g_w);
  return true;
}

void LocalMapper::Impl::checkImuConsistency(const ImuChain& chain, const Vec3& g_w) {
  // Whitened chi2 per dof of the links: 0.2-1.0 on consistent generated runs (up to 4 while an
  // offset estimate converges); a 20-30 ms offset left unestimated gave 33-60, 15 ms 17. Beyond
  // this the median link's residual is 3.2 times the noise model's sigma.
  constexpr double kImuInconsistentChi2 = 10.0;
  const double chi2 = medianInertialChi2PerDof(chain, g_w);
  log::info("IMU consistency: median inertial chi2 per dof ", chi2, " over ", chain.pims.size(), " links");
  if (chi2 > kImuInconsistentChi2 && !imu_consistency_warned) {
    imu_consistency_warned = true;
    log::warn("IMU: the inertial residuals after this estimate are ", std::sqrt(chi2),
              " times what IMU.NoiseAcc/IMU.NoiseGyro allow (median link): check IMU.T_b_c1, IMU.TimeOffset and the "
              "noise densities of the calibration");
  }
}

void LocalMapper::Impl::publishImu(const ImuInitEstimate& estimate, const char* what,
                                   bool awaiting_own_initialisation) {
  ImuState published;
  {
    std::lock_guard<std::mutex> lock(state_mutex);
    imu_state.initialised = true;
    imu_state.bias = estimate.bias;
    imu_state.g_w = estimate.g_w;
    imu_state.acceleration_covariance_w = estimate.acceleration_covariance_w;
    imu_state.awaiting_own_initialisation = awaiting_own_initialisation;
    ++imu_state.generation;
    published = imu_state;
  }
  log::info("IMU ", what, " over ", estimate.keyframes, " keyframes (", estimate.span_s, " s): g_w = (",
            published.g_w.x(), ", ", published.g_w.y(), ", ", published.g_w.z(), ") m/s^2, ",
            angleDeg(published.g_w, Vec3(0.0, 0.0, -1.0)), " deg from the map's -z, b_g = (",
            published.bias.b_g.x(), ", ", published.bias.b_g.y(), ", ", published.bias.b_g.z(), ") rad/s, b_a = (",
            published.bias.b_a.x(), ", ", published.bias.b_a.y(), ", ", published.bias.b_a.z(),
            ") m/s^2, acceleration sigma ", optim::accelerationSigma(published.acceleration_covariance_w),
            " m/s^2, generation ", published.generation);
}

// ---------------------------------------------------------------------------------------------

LocalMapper::LocalMapper(map::Atlas& atlas, const LocalMapperOptions& options, std::vector<float> level_sigma2,
                         TimingStats* timing)
    : impl_(std::make_unique<Impl>(atlas, options, std::move(level_sigma2), timing)) {
  LTLO_ASSERT(!impl_->level_sigma2.empty(), "LocalMapper needs the per-level keypoint variances");
}

LocalMapper::~LocalMapper() = default;

void LocalMapper::insertKeyFrame(std::shared_ptr<map::KeyFrame> kf) {
  LTLO_ASSERT(kf != nullptr, "insertKeyFrame(nullptr)");
  const map::KeyFrameId id = kf->id();
  if (!impl_->queue.push(std::move(kf))) {
    log::warn("local mapping finished: keyframe ", id, " not processed");
    return;
  }
  impl_->stop_ba.store(true);
}

std::size_t LocalMapper::queuedKeyFrames() const { return impl_->queue.size(); }

ImuState LocalMapper::imuState() const {
  std::lock_guard<std::mutex> lock(impl_->state_mutex);
  return impl_->imu_state;
}

void LocalMapper::setGravityFromFullBa(const Vec3& g_w) {
  Vec3 before;
  std::uint64_t generation = 0;
  {
    std::lock_guard<std::mutex> lock(impl_->state_mutex);
    if (!impl_->imu_state.initialised) return;
    before = impl_->imu_state.g_w;
    impl_->imu_state.g_w = g_w;
    generation = ++impl_->imu_state.generation;
  }
  log::info("IMU gravity from the full BA: g_w = (", g_w.x(), ", ", g_w.y(), ", ", g_w.z(), ") m/s^2, ",
            angleDeg(g_w, before), " deg from the previous estimate, ", angleDeg(g_w, Vec3(0.0, 0.0, -1.0)),
            " deg from the map's -z, generation ", generation);
}

void LocalMapper::seedImuState(const imu::ImuBias& bias, const Vec3& g_w, const Mat3& acceleration_covariance_w) {
  std::uint64_t generation = 0;
  {
    std::lock_guard<std::mutex> lock(impl_->state_mutex);
    impl_->imu_state.initialised = true;
    impl_->imu_state.bias = bias;
    impl_->imu_state.g_w = g_w;
    impl_->imu_state.acceleration_covariance_w = acceleration_covariance_w;
    generation = ++impl_->imu_state.generation;
  }
  log::info("IMU seeded from the loaded atlas: g_w = (", g_w.x(), ", ", g_w.y(), ", ", g_w.z(), ") m/s^2, ",
            angleDeg(g_w, Vec3(0.0, 0.0, -1.0)), " deg from the map's -z, b_g = (", bias.b_g.transpose(),
            ") rad/s, b_a = (", bias.b_a.transpose(), ") m/s^2, generation ", generation,
            "; refined on this run's keyframes");
}

void LocalMapper::processKeyFrame(const std::shared_ptr<map::KeyFrame>& kf) { impl_->process(kf, false); }

void LocalMapper::run() {
  log::setThreadName("mapping");
  Impl& impl = *impl_;
  while (std::optional<std::shared_ptr<map::KeyFrame>> kf = impl.queue.pop()) {
    {
      // Hold here while paused: between keyframes, with nothing of the map in hand.
      std::unique_lock<std::mutex> lock(impl.pause_mutex);
      impl.pause_cv.wait(lock, [&] { return impl.pause_requests == 0; });
      impl.processing = true;
    }
    bool failed = false;
    try {
      impl.process(*kf, true);
    } catch (const std::exception& error) {
      log::error("local mapping failed on keyframe ", (*kf)->id(), ": ", error.what());
      failed = true;
    }
    {
      std::lock_guard<std::mutex> lock(impl.pause_mutex);
      impl.processing = false;
    }
    impl.pause_cv.notify_all();
    if (failed) {
      impl.queue.close();
      break;
    }
  }
  impl.finished.store(true);
}

void LocalMapper::requestFinish() { impl_->queue.close(); }

bool LocalMapper::finished() const { return impl_->finished.load(); }

void LocalMapper::pause() {
  Impl& impl = *impl_;
  std::unique_lock<std::mutex> lock(impl.pause_mutex);
  ++impl.pause_requests;
  impl.pause_requested.store(true);
  impl.stop_ba.store(true);
  impl.pause_cv.wait(lock, [&] { return !impl.processing; });
}

void LocalMapper::resume() {
  Impl& impl = *impl_;
  {
    std::lock_guard<std::mutex> lock(impl.pause_mutex);
    if (impl.pause_requests > 0) --impl.pause_requests;
    impl.pause_requested.store(impl.pause_requests > 0);
  }
  impl.pause_cv.notify_all();
}

void LocalMapper::setKeyFrameProcessedCallback(std::function<void(const std::shared_ptr<map::KeyFrame>&)> callback) {
  std::lock_guard<std::mutex> lock(impl_->state_mutex);
  impl_->processed_callback = std::move(callback);
}

double LocalMapper::timeShift() const { return impl_->time_shift_s.load(); }

TimeOffsetStatus LocalMapper::timeOffset() const {
  std::lock_guard<std::mutex> lock(impl_->state_mutex);
  return impl_->time_offset;
}

void LocalMapper::Impl::recordTimeline(const map::KeyFrame& kf, double mapping_ms, double mapping_cpu_ms,
                                       const WindowBaStats& ba, const MappingPhaseTimes& phases) {
  MappingTimelineEntry entry;
  entry.points_ms = phases.points_ms;
  entry.ba_ms = phases.ba_ms;
  entry.keyframe_culling_ms = phases.keyframe_culling_ms;
  entry.imu_ms = phases.imu_ms;
  entry.ba_optimised_keyframes = ba.optimised_keyframes;
  entry.ba_fixed_keyframes = ba.fixed_keyframes;
  entry.ba_points = ba.points;
  entry.ba_observations = ba.observations;
  entry.ba_fixed_observations = ba.fixed_observations;
  entry.ba_fixed_observation_limit = ba.fixed_observation_limit;
  entry.ba_probe_points = ba.probe_points;
  entry.ba_iterations = ba.solver_iterations;
  entry.t_s = kf.t_s();
  entry.keyframe_id = kf.id().value;
  entry.mapping_ms = mapping_ms;
  entry.mapping_cpu_ms = mapping_cpu_ms;
  for (const map::MapId id : atlas.mapIds()) {
    map::Map* map = atlas.map(id);
    if (map == nullptr) continue;
    entry.atlas_keyframes += map->numKeyFrames();
    entry.atlas_map_points += map->numMapPoints();
  }
  entry.resident_mb = currentResidentMb();
  std::lock_guard<std::mutex> lock(state_mutex);
  timeline.push_back(entry);
}

void LocalMapper::writeState(map::ByteWriter& out) const {
  const Impl& impl = *impl_;
  LTLO_ASSERT(impl.queue.size() == 0, "local mapping's state saved with keyframes queued");
  {
    std::lock_guard<std::mutex> lock(impl.state_mutex);
    out.boolean(impl.imu_state.initialised);
    map::writeBias(impl.imu_state.bias, out);
    out.vec3(impl.imu_state.g_w);
    out.mat3(impl.imu_state.acceleration_covariance_w);
    out.u64(impl.imu_state.generation);
    out.boolean(impl.imu_state.awaiting_own_initialisation);
    const TimeOffsetStatus& offset = impl.time_offset;
    out.boolean(offset.estimated);
    out.f64(offset.shift_s);
    out.f64(offset.sigma_s);
    out.i32(offset.updates);
    out.i32(offset.boundaries_moved);
    out.f64(offset.first_estimate_t_s);
  }
  out.f64(impl.time_shift_s.load());
  impl.recent_points.writeState(out);
  out.i32(impl.sequence);
  out.f64(impl.first_imu_init_t_s);
  out.f64(impl.rest_init_t_s);
  out.f64(impl.imu_chain_floor_t_s);
  out.f64(impl.last_imu_estimate_t_s);
  out.f64(impl.last_imu_chain_end_t_s);
  out.u64(impl.imu_refinements);
  out.f64(impl.time_shift_logged_s);
  out.boolean(impl.time_offset_warned);
  out.boolean(impl.imu_consistency_warned);
}

void LocalMapper::readState(map::ByteReader& in) {
  Impl& impl = *impl_;
  ImuState imu;
  imu.initialised = in.boolean("mapping IMU initialised");
  imu.bias = map::readBias(in, "mapping bias");
  imu.g_w = in.vec3("mapping gravity");
  imu.acceleration_covariance_w = in.mat3("mapping acceleration covariance");
  imu.generation = in.u64("mapping IMU generation");
  imu.awaiting_own_initialisation = in.boolean("mapping IMU awaiting its own initialisation");
  TimeOffsetStatus offset;
  offset.estimated = in.boolean("time offset estimated");
  offset.shift_s = in.finiteF64("time offset shift");
  offset.sigma_s = in.finiteF64("time offset sigma");
  offset.updates = in.i32InRange("time offset updates", 0, std::numeric_limits<std::int32_t>::max());
  offset.boundaries_moved = in.i32InRange("time offset boundaries moved", 0, std::numeric_limits<std::int32_t>::max());
  offset.first_estimate_t_s = in.finiteF64("time offset first estimate");
  {
    std::lock_guard<std::mutex> lock(impl.state_mutex);
    impl.imu_state = imu;
    impl.time_offset = offset;
  }
  impl.time_shift_s.store(in.finiteF64("time shift"));
  impl.recent_points.readState(in);
  impl.sequence = in.i32InRange("mapping sequence", 0, std::numeric_limits<std::int32_t>::max());
  impl.first_imu_init_t_s = in.finiteF64("first IMU initialisation time");
  impl.rest_init_t_s = in.finiteF64("IMU initialisation at rest time");
  impl.imu_chain_floor_t_s = in.finiteF64("IMU chain floor after a rejected initialisation");
  impl.last_imu_estimate_t_s = in.finiteF64("last IMU estimate time");
  impl.last_imu_chain_end_t_s = in.finiteF64("last IMU chain end");
  const std::uint64_t refinements_offset = in.fileOffset();
  const std::uint64_t refinements = in.u64("IMU refinements done");
  if (refinements > impl.options.imu_refinement_delays_s.size()) {
    in.failAt(refinements_offset,
              "IMU refinements beyond the " + std::to_string(impl.options.imu_refinement_delays_s.size()) + " scheduled",
              std::to_string(refinements));
  }
  impl.imu_refinements = static_cast<std::size_t>(refinements);
  impl.time_shift_logged_s = in.finiteF64("time shift logged");
  impl.time_offset_warned = in.boolean("time offset warned");
  impl.imu_consistency_warned = in.boolean("IMU consistency warned");
}

std::vector<MappingTimelineEntry> LocalMapper::timeline() const {
  std::lock_guard<std::mutex> lock(impl_->state_mutex);
  return impl_->timeline;
}

LocalMapperCounters LocalMapper::counters() const {
  std::lock_guard<std::mutex> lock(impl_->state_mutex);
  return impl_->counters;
}

}  // namespace ltlo::mapping
