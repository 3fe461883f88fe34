#include "imu_initializer.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/optim/bundle_adjust.h"

namespace ltlo::mapping {

ImuChain imuChainEndingAt(const map::Map& map, const std::shared_ptr<map::KeyFrame>& newest) {
  ImuChain chain;
  if (!newest || newest->isBad()) return chain;
  std::vector<std::shared_ptr<map::KeyFrame>> reversed{newest};
  std::vector<std::shared_ptr<const imu::Preintegrated>> reversed_pims;
  std::shared_ptr<map::KeyFrame> current = newest;
  while (true) {
    const std::optional<imu::Preintegrated> pim = current->imuFromPrevious();
    const std::shared_ptr<map::KeyFrame> previous = map.keyFrame(current->previousKeyFrame());
    if (!pim || !previous || previous->isBad() || pim->dt_s() <= 0.0) break;
    reversed_pims.push_back(std::make_shared<const imu::Preintegrated>(*pim));
    reversed.push_back(previous);
    current = previous;
  }
  chain.keyframes.assign(reversed.rbegin(), reversed.rend());
  chain.pims.assign(reversed_pims.rbegin(), reversed_pims.rend());
  return chain;
}

ImuChain startAfter(ImuChain chain, double floor_t_s) {
  if (floor_t_s < 0.0) return chain;
  std::size_t first = 0;
  while (first < chain.keyframes.size() && chain.keyframes[first]->t_s() <= floor_t_s) ++first;
  chain.keyframes.erase(chain.keyframes.begin(), chain.keyframes.begin() + static_cast<std::ptrdiff_t>(first));
  // pims[k] links keyframes k and k + 1: the links into the dropped keyframes go with them.
  const std::size_t dropped_links = std::min(first, chain.pims.size());
  chain.pims.erase(chain.pims.begin(), chain.pims.begin() + static_cast<std::ptrdiff_t>(dropped_links));
  return chain;
}

ImuChain endAtStaticView(ImuChain chain, double min_static_ratio) {
  while (!chain.keyframes.empty() && chain.keyframes.back()->staticAreaRatio() < min_static_ratio) {
    chain.keyframes.pop_back();
    if (!chain.pims.empty()) chain.pims.pop_back();
  }
  return chain;
}

double medianInertialChi2PerDof(const ImuChain& chain, const Vec3& g_w) {
  std::vector<double> chi2;
  for (std::size_t k = 0; k + 1 < chain.keyframes.size() && k < chain.pims.size(); ++k) {
    const map::KeyFrame& a = *chain.keyframes[k];
    const map::KeyFrame& b = *chain.keyframes[k + 1];
    const imu::Preintegrated& pim = *chain.pims[k];
    if (pim.dt_s() <= 0.0) continue;
    const imu::NavState state_a{a.T_w_b().rotationMatrix(), a.T_w_b().translation(), a.v_w_b()};
    const imu::NavState state_b{b.T_w_b().rotationMatrix(), b.T_w_b().translation(), b.v_w_b()};
    const Vec9 r = imu::inertialResidual(state_a, state_b, a.bias(), pim, g_w);
    const double value = r.dot(pim.information() * r) / 9.0;
    if (std::isfinite(value)) chi2.push_back(value);
  }
  if (chi2.empty()) return 0.0;
  std::nth_element(chi2.begin(), chi2.begin() + static_cast<std::ptrdiff_t>(chi2.size() / 2), chi2.end());
  return chi2[chi2.size() / 2];
}

std::optional<ImuInitEstimate> initialiseImuOnChain(const ImuChain& chain, const ImuInitOptions& options,
                                                    const imu::ImuBias& bias_init, const imu::RestEstimate* rest) {
  LTLO_ASSERT(chain.keyframes.size() >= 3 && chain.pims.size() + 1 == chain.keyframes.size(),
              "IMU initialisation on a chain of " << chain.keyframes.size() << " keyframes and "
                                                  << chain.pims.size() << " preintegrations");
  optim::ImuInitProblem problem;
  for (const std::shared_ptr<map::KeyFrame>& kf : chain.keyframes) problem.T_w_b.push_back(kf->T_w_b());
  problem.pims = chain.pims;
  problem.bias_init = bias_init;
  const optim::BiasPriorInformation prior =
      optim::biasPriorInformation(chain.pims.front()->noise(), chain.span_s(), options.bias_prior_samples);
  problem.gyro_bias_prior_information = prior.gyro;
  problem.acc_bias_prior_information = prior.acc;
  problem.iterations = options.iterations;
  if (rest != nullptr) {
    problem.known_R_w_g = Quat::FromTwoVectors(Vec3(0.0, 0.0, -1.0), rest->g_w.normalized()).toRotationMatrix();
    problem.bias_init.b_g = rest->b_g;
    problem.gyro_bias_prior_mean = rest->b_g;
    const imu::ImuNoise& noise = chain.pims.front()->noise();
    const double variance = noise.gyro_density * noise.gyro_density / std::max(rest->rest_s, 1e-3) +
                            noise.gyro_walk_density * noise.gyro_walk_density * (chain.span_s() + rest->rest_s);
    problem.gyro_bias_prior_information = 1.0 / variance;
  }
  const optim::ImuInitResult result = optim::initializeImu(problem);
  bool finite = result.g_w.allFinite() && result.bias.b_g.allFinite() && result.bias.b_a.allFinite();
  for (const Vec3& v : result.v_w_b) finite = finite && v.allFinite();
  if (!finite) return std::nullopt;
  for (std::size_t k = 0; k < chain.keyframes.size(); ++k) {
    if (chain.keyframes[k]->isBad()) continue;
    chain.keyframes[k]->setVelocity(result.v_w_b[k]);
    chain.keyframes[k]->setBias(result.bias);
  }
  ImuInitEstimate estimate;
  estimate.g_w = result.g_w;
  estimate.bias = result.bias;
  estimate.keyframes = static_cast<int>(chain.keyframes.size());
  estimate.span_s = chain.span_s();
  estimate.final_chi2 = result.summary.final_chi2;
  estimate.acceleration_covariance_w = result.acceleration_covariance_w;
  return estimate;
}

std::optional<ImuInitEstimate> initialiseImuAtRest(const ImuChain& chain, double min_rest_s,
                                                   double acc_bias_sigma_m_s2) {
  if (chain.keyframes.size() < 2) return std::nullopt;
  map::KeyFrame& rest = *chain.keyframes.back();
  map::KeyFrame& previous = *chain.keyframes[chain.keyframes.size() - 2];
  std::optional<imu::Preintegrated> link = rest.imuFromPrevious();
  if (!link || link->dt_s() < min_rest_s || link->dt_s() <= 0.0) return std::nullopt;
  const double dt_s = link->dt_s();
  imu::ImuBias bias = link->bias();
  // Two passes: the second reintegrates at the first's gyro bias (the residual rotation is then
  // second order).
  for (int pass = 0; pass < 2; ++pass) {
    bias.b_g += so3Log(link->deltaR()) / dt_s;
    link->reintegrate(bias);
  }
  constexpr double kMaxRestRate_rad_s = 0.01;
  const Vec3 residual_rate = so3Log(link->deltaR()) / dt_s;
  if (!bias.b_g.allFinite() || residual_rate.norm() > kMaxRestRate_rad_s) return std::nullopt;
  const Vec3 f_b = link->deltaV() / dt_s;  // mean specific force, bias-corrected, in previous's body frame
  if (!f_b.allFinite() || f_b.norm() < 0.5 * imu::kGravity_m_s2) return std::nullopt;
  ImuInitEstimate estimate;
  estimate.g_w = -imu::kGravity_m_s2 * (previous.T_w_b().rotationMatrix() * f_b).normalized();
  estimate.bias = bias;
  estimate.keyframes = 2;
  estimate.span_s = dt_s;
  const imu::ImuNoise& noise = link->noise();
  const double mean_noise_var = noise.acc_density * noise.acc_density / dt_s;
  estimate.acceleration_covariance_w = (acc_bias_sigma_m_s2 * acc_bias_sigma_m_s2 + mean_noise_var) * Mat3::Identity();
  for (const std::shared_ptr<map::KeyFrame>& kf : chain.keyframes) {
    if (!kf->isBad()) kf->setBias(bias);
  }
  previous.setVelocity(Vec3::Zero());
  rest.setVelocity(Vec3::Zero());
  rest.setImuFromPrevious(std::move(link));  // linearised at the estimate
  return estimate;
}

namespace {

/// optim::inertialAccelerationCovariance over the newest `max_keyframes` of `chain` at the chain's
/// current velocities, the newest bias and `g_w` (after a refinement: the inertial evidence alone,
/// so the visual part of the refinement can only make the truth better known than this).
/// T_w_b / v_w_b: the states of the chain's newest T_w_b.size() keyframes (pims between them from
/// the chain), `bias` the newest bias.
Mat3 chainAccelerationCovariance(const ImuChain& chain, const std::vector<SE3>& T_w_b,
                                 const std::vector<Vec3>& v_w_b, const imu::ImuBias& bias, const Vec3& g_w,
                                 const ImuInitOptions& options) {
  const std::size_t count = chain.keyframes.size();
  const std::size_t window = T_w_b.size();
  LTLO_ASSERT(window >= 2 && window <= count && v_w_b.size() == window,
              "chainAccelerationCovariance: " << window << " states for a chain of " << count);
  const std::size_t first = count - window;
  optim::ImuInitProblem problem;
  optim::ImuInitResult estimate;
  problem.T_w_b = T_w_b;
  estimate.v_w_b = v_w_b;
  for (std::size_t k = first + 1; k < count; ++k) problem.pims.push_back(chain.pims[k - 1]);
  const double span_s = chain.keyframes.back()->t_s() - chain.keyframes[first]->t_s();
  const optim::BiasPriorInformation prior =
      optim::biasPriorInformation(chain.pims.front()->noise(), span_s, options.bias_prior_samples);
  problem.gyro_bias_prior_information = prior.gyro;
  problem.acc_bias_prior_information = prior.acc;
  problem.bias_init = bias;
  estimate.bias = bias;
  estimate.R_w_g = imu::gravityRotationFromDirection(g_w);
  estimate.g_w = g_w;
  return optim::inertialAccelerationCovariance(problem, estimate);
}

bool usable(const std::shared_ptr<map::KeyFrame>& kf) { return kf != nullptr && !kf->isBad(); }

double gammaOf(const map::KeyFrame& kf, const std::vector<double>& gamma, int keypoint) {
  const int cluster = kf.clusterOf(keypoint);
  return cluster >= 0 && cluster < static_cast<int>(gamma.size()) ? gamma[static_cast<std::size_t>(cluster)] : 1.0;
}

/// A keyframe of the refinement's problem (problem order).
struct RefinementEntry {
  std::shared_ptr<map::KeyFrame> kf;
  bool fixed = false;
  bool pose_only = false;  ///< gauge: pose held, velocity and biases optimised
  std::vector<double> gamma;
};

/// The keyframes of the refinement and the points they see.
struct RefinementWindow {
  std::vector<RefinementEntry> entries;
  std::unordered_map<map::KeyFrameId, std::size_t> index_of;
  /// entries [0, optimised_end) are the chain's (the optimised ones and the one before them)
  std::size_t optimised_end = 0;
  /// the map points seen by the optimised keyframes, in the order first seen
  std::vector<std::shared_ptr<map::MapPoint>> candidates;

  void add(const std::shared_ptr<map::KeyFrame>& kf, bool fixed) {
    if (!usable(kf) || !index_of.emplace(kf->id(), entries.size()).second) return;
    entries.push_back({kf, fixed, false, kf->gamma()});
  }
};

/// The chain's keyframes from `first` (optimised) and the one before them (held), with the inertial
/// links between them in `problem`; false when no link is left.
bool addChainKeyFrames(const ImuChain& chain, std::size_t first, RefinementWindow* window,
                       optim::LocalBaProblem* problem) {
  const std::size_t count = chain.keyframes.size();
  const std::size_t border = first > 0 ? first - 1 : first;
  for (std::size_t k = border; k < count; ++k) window->add(chain.keyframes[k], k < first);
  for (std::size_t k = border + 1; k < count; ++k) {
    const auto i = window->index_of.find(chain.keyframes[k - 1]->id());
    const auto j = window->index_of.find(chain.keyframes[k]->id());
    if (i == window->index_of.end() || j == window->index_of.end()) continue;
    problem->inertial.push_back({static_cast<int>(i->second), static_cast<int>(j->second), chain.pims[k - 1]});
  }
  if (problem->inertial.empty()) return false;
  window->optimised_end = window->entries.size();
  return true;
}

/// The points seen by the optimised keyframes (beta at least min_point_beta) and, held, up to
/// `max_observers` other keyframes seeing most of them; without any held keyframe the oldest of the
/// chain is the gauge.
void addObservedPoints(const map::Map& map, double min_point_beta, std::size_t max_observers,
                       RefinementWindow* window) {
  std::vector<RefinementEntry>& entries = window->entries;
  const std::size_t optimised_end = window->optimised_end;
  std::unordered_set<map::MapPointId> seen;
  std::unordered_map<map::KeyFrameId, int> observer_counts;
  for (std::size_t k = 0; k < optimised_end; ++k) {
    if (entries[k].fixed) continue;
    for (const map::MapPointId id : entries[k].kf->mapPoints()) {
      if (!id.valid() || !seen.insert(id).second) continue;
      const std::shared_ptr<map::MapPoint> point = map.mapPoint(id);
      if (!point || point->isBad() || point->beta() < min_point_beta) continue;
      window->candidates.push_back(point);
      for (const auto& [observer, index] : point->observations()) {
        if (window->index_of.count(observer) == 0) ++observer_counts[observer];
      }
    }
  }
  std::vector<std::pair<int, map::KeyFrameId>> by_count;
  for (const auto& [id, observations] : observer_counts) by_count.emplace_back(-observations, id);
  std::sort(by_count.begin(), by_count.end());
  for (const auto& [negative_count, id] : by_count) {
    if (entries.size() - optimised_end >= max_observers) break;
    window->add(map.keyFrame(id), true);
  }
  if (std::none_of(entries.begin(), entries.end(), [](const RefinementEntry& e) { return e.fixed; })) {
    entries.front().fixed = true;  // the oldest of the chain: gauge (gravity is optimised)
    entries.front().pose_only = true;
  }
}

/// The problem's camera model, gravity, weights and keyframe states, and the weak zero-mean bias
/// prior on the chain's oldest optimised keyframe (chain.keyframes[first]).
void setUpRefinementProblem(const ImuChain& chain, std::size_t first, const Vec3& g_w, const ImuInitOptions& options,
                            const RefinementContext& context, const RefinementWindow& window,
                            optim::LocalBaProblem* problem) {
  const map::KeyFrame& newest = *chain.keyframes.back();
  problem->model.camera = newest.camera();
  problem->model.T_c_x = newest.T_b_c().inverse();
  problem->model.bf_px_m = context.bf_px_m;
  problem->g_w = g_w;
  problem->estimate_gravity = true;
  problem->lambda_imu = context.lambda_imu;
  for (std::size_t k = 0; k < window.entries.size(); ++k) {
    const RefinementEntry& entry = window.entries[k];
    optim::BaKeyFrame v;
    v.id = static_cast<int>(k);
    v.T_w_b = entry.kf->T_w_b();
    v.v_w_b = entry.kf->v_w_b();
    v.bias = entry.kf->bias();
    v.fixed = entry.fixed;
    v.fixed_pose_only = entry.pose_only;
    problem->keyframes.push_back(v);
  }
  // The weak zero-mean bias prior (as the initialisation's) on the oldest optimised keyframe; the
  // random walk carries it along the chain.
  const optim::BiasPriorInformation prior =
      optim::biasPriorInformation(chain.pims.front()->noise(), chain.span_s(), options.bias_prior_samples);
  const auto oldest_free = window.index_of.find(chain.keyframes[first]->id());
  if ((prior.gyro > 0.0 || prior.acc > 0.0) && oldest_free != window.index_of.end()) {
    problem->bias_priors.push_back({static_cast<int>(oldest_free->second), imu::ImuBias(), prior.gyro, prior.acc});
  }
}

/// The candidate points seen by at least two of the window's keyframes and their observations into
/// `problem`; returns the points in problem order.
std::vector<std::shared_ptr<map::MapPoint>> addPointObservations(const RefinementWindow& window,
                                                                 const RefinementContext& context,
                                                                 optim::LocalBaProblem* problem) {
  std::vector<std::shared_ptr<map::MapPoint>> points;
  for (const std::shared_ptr<map::MapPoint>& point : window.candidates) {
    const int point_id = static_cast<int>(points.size());
    const double beta = point->beta();
    std::vector<optim::BaObservation> observations;
    for (const auto& [observer, index] : point->observations()) {
      const auto it = window.index_of.find(observer);
      if (it == window.index_of.end()) continue;
      const RefinementEntry& entry = window.entries[it->second];
      if (index < 0 || index >= entry.kf->numKeypoints()) continue;
      const features::Keypoint& kp = entry.kf->keypoints()[static_cast<std::size_t>(index)];
      const std::size_t level =
          std::min<std::size_t>(static_cast<std::size_t>(std::max(kp.octave, 0)), context.level_sigma2.size() - 1);
      optim::BaObservation obs;
      obs.keyframe_id = static_cast<int>(it->second);
      obs.point_id = point_id;
      obs.uv = Vec2(kp.x_px, kp.y_px);
      obs.depth_m = entry.kf->depth_m(index);
      obs.sigma_px = std::sqrt(static_cast<double>(context.level_sigma2[level]));
      obs.static_weight = beta * gammaOf(*entry.kf, entry.gamma, index);
      observations.push_back(obs);
    }
    if (observations.size() < 2) continue;
    problem->points.push_back(optim::BaPoint{point_id, point->p_w()});
    points.push_back(point);
    problem->observations.insert(problem->observations.end(), observations.begin(), observations.end());
  }
  return points;
}

/// What the refinement's BA held, optimised and found.
ImuRefinementStats refinementStats(const RefinementWindow& window, std::size_t num_points,
                                   const optim::LocalBaProblem& problem, const optim::LocalBaResult& result) {
  ImuRefinementStats stats;
  for (const RefinementEntry& e : window.entries) (e.fixed ? stats.fixed_keyframes : stats.optimised_keyframes)++;
  stats.points = static_cast<int>(num_points);
  stats.observations = static_cast<int>(problem.observations.size());
  stats.visual_sigma_scale = std::sqrt(problem.inertial_information_scale);
  stats.initial_chi2 = result.initial_chi2;
  stats.final_chi2 = result.summary.final_chi2;
  return stats;
}

/// Gravity and the chain keyframes' states [0, optimised_end) of the BA result are finite.
bool refinedStatesFinite(const optim::LocalBaResult& result, std::size_t optimised_end) {
  bool finite = result.g_w.allFinite();
  for (std::size_t k = 0; k < optimised_end; ++k) {
    const optim::BaKeyFrame& out = result.keyframes[k];
    finite = finite && out.T_w_b.translation().allFinite() && out.T_w_b.quaternion().coeffs().allFinite() &&
             out.v_w_b.allFinite() && out.bias.b_g.allFinite() && out.bias.b_a.allFinite();
  }
  return finite;
}

/// The refined estimate's own uncertainty (inertial evidence over the optimised keyframes, the
/// chain's from `first`); nullopt when one of them went bad meanwhile.
std::optional<Mat3> refinedAccelerationCovariance(const ImuChain& chain, std::size_t first,
                                                  const RefinementWindow& window,
                                                  const optim::LocalBaResult& result, const ImuInitOptions& options) {
  const std::size_t count = chain.keyframes.size();
  std::vector<SE3> refined_T_w_b;
  std::vector<Vec3> refined_v_w_b;
  for (std::size_t k = first; k < count; ++k) {
    const auto it = window.index_of.find(chain.keyframes[k]->id());
    if (it == window.index_of.end()) break;
    refined_T_w_b.push_back(result.keyframes[it->second].T_w_b);
    refined_v_w_b.push_back(result.keyframes[it->second].v_w_b);
  }
  if (refined_T_w_b.size() != count - first) return std::nullopt;  // a chain keyframe went bad meanwhile
  return chainAccelerationCovariance(chain, refined_T_w_b, refined_v_w_b,
                                     result.keyframes[window.optimised_end - 1].bias, result.g_w, options);
}

/// The refined states of the chain's keyframes and the points' positions into the map (what went
/// bad meanwhile is skipped).
void writeRefinement(map::Map& map, const RefinementWindow& window,
                     const std::vector<std::shared_ptr<map::MapPoint>>& points, const optim::LocalBaResult& result) {
  for (std::size_t k = 0; k < window.optimised_end; ++k) {
    const RefinementEntry& entry = window.entries[k];
    map::KeyFrame& kf = *entry.kf;
    const optim::BaKeyFrame& out = result.keyframes[k];
    if (kf.isBad() || (entry.fixed && !entry.pose_only)) continue;
    if (!entry.fixed) kf.setPose_T_w_b(out.T_w_b);
    kf.setVelocity(out.v_w_b);
    kf.setBias(out.bias);
  }
  for (std::size_t m = 0; m < points.size(); ++m) {
    if (!points[m]->isBad() && result.points[m].p_w.allFinite()) points[m]->setPosition(result.points[m].p_w);
  }
  map.bumpVersion();
}

}  // namespace

std::optional<ImuInitEstimate> refineImuWithVisualInertialBa(map::Map& map, const ImuChain& chain, const Vec3& g_w,
                                                             const ImuInitOptions& options,
                                                             const RefinementContext& context,
                                                             ImuRefinementStats* stats) {
  LTLO_ASSERT(chain.keyframes.size() >= 2 && chain.pims.size() + 1 == chain.keyframes.size(),
              "IMU refinement on a chain of " << chain.keyframes.size() << " keyframes and " << chain.pims.size()
                                              << " preintegrations");
  LTLO_ASSERT(!context.level_sigma2.empty(), "IMU refinement needs the per-level keypoint variances");
  // ---- keyframes: the chain's latest (optimised), the one before them (held), observers (held) ----
  const std::size_t count = chain.keyframes.size();
  const std::size_t window_size =
      std::min<std::size_t>(count, static_cast<std::size_t>(std::max(3, options.refine_max_keyframes)));
  const std::size_t first = count - window_size;
  RefinementWindow window;
  optim::LocalBaProblem problem;
  if (!addChainKeyFrames(chain, first, &window, &problem)) return std::nullopt;
  addObservedPoints(map, context.min_point_beta, window_size, &window);

  // ---- the problem ----
  setUpRefinementProblem(chain, first, g_w, options, context, window, &problem);
  const std::vector<std::shared_ptr<map::MapPoint>> points = addPointObservations(window, context, &problem);
  if (context.visual_variance_estimation) problem.inertial_information_scale = optim::inertialInformationScale(problem);

  optim::LocalBaOptions ba_options;
  ba_options.iterations = options.refine_iterations;
  ba_options.num_threads = context.num_threads;
  const optim::LocalBaResult result = optim::localBundleAdjust(problem, ba_options);
  if (stats != nullptr) *stats = refinementStats(window, points.size(), problem, result);
  if (!refinedStatesFinite(result, window.optimised_end)) return std::nullopt;
  const std::optional<Mat3> acceleration_covariance_w =
      refinedAccelerationCovariance(chain, first, window, result, options);
  if (!acceleration_covariance_w) return std::nullopt;
  const double sigma_m_s2 = optim::accelerationSigma(*acceleration_covariance_w);
  if (!(sigma_m_s2 <= context.max_acceleration_sigma_m_s2)) {
    log::info("IMU refinement not applied: acceleration sigma ", sigma_m_s2, " m/s^2 over ", window_size,
              " keyframes, the current estimate's is ", context.max_acceleration_sigma_m_s2, " m/s^2");
    return std::nullopt;
  }
  const Vec3& refined_b_a = result.keyframes[window.optimised_end - 1].bias.b_a;
  if (!(refined_b_a.norm() <= context.max_acc_bias_m_s2)) {
    log::info("IMU refinement not applied: accelerometer bias (", refined_b_a.transpose(), ") m/s^2 beyond ",
              context.max_acc_bias_m_s2, " m/s^2 (ImuInit.MaxAccBias), g_w = (", result.g_w.transpose(), ")");
    if (stats != nullptr) stats->implausible_bias = true;
    return std::nullopt;
  }

  // ---- write back (what went bad meanwhile is skipped) ----
  writeRefinement(map, window, points, result);

  ImuInitEstimate estimate;
  estimate.g_w = result.g_w;
  estimate.bias = result.keyframes[window.optimised_end - 1].bias;
  estimate.keyframes = static_cast<int>(window_size);
  estimate.span_s = chain.keyframes.back()->t_s() - chain.keyframes[first]->t_s();
  estimate.final_chi2 = result.summary.final_chi2;
  estimate.acceleration_covariance_w = *acceleration_covariance_w;
  return estimate;
}

void predictInertialState(const map::Map& map, map::KeyFrame& kf, const Vec3& g_w) {
  const std::shared_ptr<map::KeyFrame> previous = map.keyFrame(kf.previousKeyFrame());
  const std::optional<imu::Preintegrated> pim = kf.imuFromPrevious();
  if (!previous || previous->isBad() || !pim) return;
  const imu::ImuBias previous_bias = previous->bias();
  const imu::ImuBias bias = kf.bias();
  if (bias.b_g.isZero() && bias.b_a.isZero()) kf.setBias(previous_bias);
  if (!kf.v_w_b().isZero()) return;
  imu::NavState state_i;
  const SE3 T_w_b_i = previous->T_w_b();
  state_i.R_w_b = T_w_b_i.rotationMatrix();
  state_i.p_w_b = T_w_b_i.translation();
  state_i.v_w_b = previous->v_w_b();
  kf.setVelocity(imu::predict(state_i, *pim, previous_bias, g_w).v_w_b);
}

std::optional<ImuInitEstimate> estimateImu(map::Map& map, const ImuChain& chain, const ImuInitOptions& options,
                                           const RefinementContext& context,
                                           const std::optional<ImuInitEstimate>& current, bool* implausible_bias) {
  const map::KeyFrameId newest = chain.keyframes.back()->id();
  auto refine = [&](const Vec3& g_w, const RefinementContext& refine_context, bool* implausible) {
    ImuRefinementStats stats;
    const std::optional<ImuInitEstimate> refined =
        refineImuWithVisualInertialBa(map, chain, g_w, options, refine_context, &stats);
    log::info("IMU visual-inertial BA at kf ", newest, ": ", stats.optimised_keyframes, " keyframes optimised, ",
              stats.fixed_keyframes, " held, ", stats.points, " points, ", stats.observations,
              " observations (camera noise ", stats.visual_sigma_scale, " x the model), chi2 ",
              stats.initial_chi2, " -> ", stats.final_chi2, (refined ? "" : " (not applied)"));
    if (implausible != nullptr) *implausible = stats.implausible_bias;
    return refined;
  };
  if (current && options.visual_inertial_refinement) return refine(current->g_w, context, nullptr);
  // A first initialisation: ImuInit.MaxAccBias gates the estimate that would be applied. The
  // inertial-only step writes its velocities and bias to the chain's keyframes; a rejected estimate
  // leaves them as they were (the refinement writes only what it applies).
  const bool gated = !current && options.max_acc_bias_m_s2 > 0.0;
  std::vector<std::pair<Vec3, imu::ImuBias>> states_before;
  if (gated) {
    for (const std::shared_ptr<map::KeyFrame>& kf : chain.keyframes) states_before.emplace_back(kf->v_w_b(), kf->bias());
  }
  auto reject = [&](const ImuInitEstimate& estimate, const char* which) -> std::optional<ImuInitEstimate> {
    for (std::size_t k = 0; k < chain.keyframes.size(); ++k) {
      chain.keyframes[k]->setVelocity(states_before[k].first);
      chain.keyframes[k]->setBias(states_before[k].second);
    }
    log::warn("IMU initialisation at kf ", newest, " rejected: ", which, " accelerometer bias (",
              estimate.bias.b_a.transpose(), ") m/s^2, |b_a| ", estimate.bias.b_a.norm(), " beyond ImuInit.MaxAccBias ",
              options.max_acc_bias_m_s2, " (g_w = (", estimate.g_w.transpose(), ")): the tracked poses of its ",
              chain.keyframes.size(), " keyframes do not fit the IMU");
    if (implausible_bias != nullptr) *implausible_bias = true;
    return std::nullopt;
  };
  auto plausible = [&](const ImuInitEstimate& estimate) {
    return !gated || estimate.bias.b_a.norm() <= options.max_acc_bias_m_s2;
  };
  const std::optional<ImuInitEstimate> inertial_only =
      initialiseImuOnChain(chain, options, current ? current->bias : imu::ImuBias());
  if (!inertial_only) return inertial_only;
  if (current || !options.visual_inertial_refinement) {
    return plausible(*inertial_only) ? inertial_only : reject(*inertial_only, "its");
  }
  log::info("IMU inertial-only initialisation at kf ", newest, ": g_w = (", inertial_only->g_w.transpose(),
            ") m/s^2, b_g = (", inertial_only->bias.b_g.transpose(), ") rad/s, b_a = (",
            inertial_only->bias.b_a.transpose(), ") m/s^2");
  RefinementContext first_context = context;
  if (gated) first_context.max_acc_bias_m_s2 = options.max_acc_bias_m_s2;
  bool refined_implausible = false;
  const std::optional<ImuInitEstimate> refined = refine(inertial_only->g_w, first_context, &refined_implausible);
  if (refined) return refined;
  if (refined_implausible) return reject(*inertial_only, "refined, and inertial-only");
  return plausible(*inertial_only) ? inertial_only : reject(*inertial_only, "its");
}

}  // namespace ltlo::mapping
