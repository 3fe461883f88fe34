#include "local_window_ba.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "ltlo/core/log.h"
#include "ltlo/map/map_point.h"
#include "ltlo/optim/bundle_adjust.h"
#include "ltlo/optim/local_ba_graph.h"

namespace ltlo::mapping {

namespace {

/// Points closer than this to a camera are not projected for Eq. 56 (m).
constexpr double kMinProjectionDepth_m = 0.1;
/// |r|^2 given to an observation whose point lies behind its camera (no meaningful residual): far
/// beyond any chi2 gate, so the scores treat it as the gross outlier it is.
constexpr double kBehindCameraRsq = 1e4;

struct WindowKeyFrame {
  std::shared_ptr<map::KeyFrame> kf;
  bool fixed = false;
  std::vector<double> gamma;  ///< the keyframe's cluster scores (copied once)
  bool velocity_free = false;  ///< fixed, but the velocity optimised (the gauge, gauge_velocity_free)
  double velocity_prior_sigma_m_s = 0.0;  ///< with velocity_free: the prior's sigma (0: none)
  Vec3 velocity_prior = Vec3::Zero();     ///< and its mean
};

struct ObservationRef {
  std::size_t keyframe;
  std::size_t point;
  int index;
};

/// What Eq. 56 needs of a map point to project it into a keyframe: the viewing cone and distance
/// range in which it is expected to be visible (as ORB-SLAM's and the fusion's visibility test).
struct Visibility {
  Vec3 normal_w = Vec3::Zero();
  double min_distance_m = 0.0;
  double max_distance_m = 0.0;
};

/// A map point outside the problem (seen by the fixed keyframes only) projected for Eq. 56.
struct ProbePoint {
  Vec3 p_w;
  double beta = 1.0;
  Visibility visibility;
};

/// The keyframes, points and observations of one window and the BA problem built from them.
struct Window {
  std::vector<WindowKeyFrame> keyframes;
  std::vector<std::shared_ptr<map::MapPoint>> points;  ///< problem order
  std::vector<Visibility> visibility;                  ///< problem order
  /// Per point: the window keyframe of its only observation in the map, -1 when it has several
  /// (a point made from one keyframe's depth says nothing about that keyframe's depth, Eq. 56).
  std::vector<int> sole_observer;
  std::vector<ObservationRef> refs;                    ///< problem order
  std::vector<ProbePoint> probes;
  optim::LocalBaProblem problem;
  int fixed_observations = 0;               ///< observations in the problem by fixed keyframes
  std::size_t fixed_observation_limit = 0;  ///< the per-point limit applied (0: none)
};

/// A point seen from outside its distance range or viewing cone is not expected in the image
/// (map_point.h's visibility test).
using map::kMaxDistanceFactor;
using map::kMinDistanceFactor;
using map::kMinViewingCos;

Visibility visibilityOf(const map::MapPoint& point) {
  return {point.normal_w(), point.minDistance_m(), point.maxDistance_m()};
}

bool expectedVisible(const Visibility& v, const Vec3& p_w, const Vec3& centre_w) {
  const Vec3 ray_w = p_w - centre_w;
  const double distance_m = ray_w.norm();
  if (v.max_distance_m > 0.0 &&
      (distance_m < kMinDistanceFactor * v.min_distance_m || distance_m > kMaxDistanceFactor * v.max_distance_m)) {
    return false;
  }
  return v.normal_w.isZero() || ray_w.dot(v.normal_w) >= kMinViewingCos * distance_m;
}

int baId(map::KeyFrameId id) { return static_cast<int>(id.value); }
int baId(map::MapPointId id) { return static_cast<int>(id.value); }

double gammaOfKeypoint(const WindowKeyFrame& entry, int i) {
  const int cluster = entry.kf->clusterOf(i);
  return cluster >= 0 && cluster < static_cast<int>(entry.gamma.size()) ? entry.gamma[static_cast<std::size_t>(cluster)]
                                                                        : 1.0;
}

bool usable(const std::shared_ptr<map::KeyFrame>& kf) { return kf != nullptr && !kf->isBad(); }

/// The window's keyframes by id: index into Window::keyframes.
using KeyFrameIndex = std::unordered_map<map::KeyFrameId, std::size_t>;

void addKeyFrame(const std::shared_ptr<map::KeyFrame>& k, bool fixed, Window* window, KeyFrameIndex* index_of) {
  if (!index_of->emplace(k->id(), window->keyframes.size()).second) return;
  window->keyframes.push_back({k, fixed, k->gamma(), false});
}

/// The optimised window (and, inertial, the fixed keyframe before it, with the inertial links):
/// kf and the keyframes before it, else kf's best covisibles. The map's gauge keyframe is held.
void addOptimisedKeyFrames(map::Map& map, const std::shared_ptr<map::KeyFrame>& kf, const WindowBaOptions& options,
                           Window* window, KeyFrameIndex* index_of) {
  std::vector<WindowKeyFrame>& keyframes = window->keyframes;
  const std::size_t window_size = static_cast<std::size_t>(std::max(1, options.window_size));
  addKeyFrame(kf, false, window, index_of);
  if (options.inertial) {
    std::shared_ptr<map::KeyFrame> newer = kf;
    while (true) {
      const std::shared_ptr<map::KeyFrame> older = map.keyFrame(newer->previousKeyFrame());
      const std::optional<imu::Preintegrated> pim = newer->imuFromPrevious();
      if (!usable(older) || !pim) break;
      const bool border = keyframes.size() >= window_size;
      addKeyFrame(older, border, window, index_of);
      window->problem.inertial.push_back({baId(older->id()), baId(newer->id()),
                                          std::make_shared<const imu::Preintegrated>(*pim)});
      if (border) break;
      newer = older;
    }
  } else {
    for (const map::KeyFrameId id : kf->bestCovisibles(window_size - 1)) {
      const std::shared_ptr<map::KeyFrame> other = map.keyFrame(id);
      if (usable(other)) addKeyFrame(other, false, window, index_of);
    }
  }
  const map::KeyFrameId gauge = map.gaugeKeyFrame();
  // A map started at the IMU's prediction after a loss (it has an origin in its parent's world):
  // its gauge holds the window's pose, but its velocity is the dead reckoning's and is estimated.
  // The first map's gauge keeps the velocity of the IMU initialisation (at rest: zero).
  const std::optional<map::MapOrigin> origin = map.origin();
  const bool gauge_velocity_free = options.inertial && options.gauge_velocity_free && origin.has_value();
  for (WindowKeyFrame& entry : keyframes) {
    if (entry.kf->id() == gauge || entry.kf->isAnchor()) entry.fixed = true;
    if (entry.kf->id() == gauge && !entry.kf->isAnchor() && gauge_velocity_free) {
      entry.velocity_free = true;
      // LocalMapping.GaugeVelocityPrior: about the velocity the map started with, to the
      // prediction's uncertainty (only while the gauge is still the keyframe the map started at).
      if (options.gauge_velocity_prior && origin->sigma_velocity_m_s > 0.0 &&
          std::abs(entry.kf->t_s() - origin->t_s) < 1e-6) {
        entry.velocity_prior_sigma_m_s = origin->sigma_velocity_m_s;
        entry.velocity_prior = origin->v_w_b_dead_reckoned;
      }
    }
  }
}

/// The valid ids of kf's points not in *point_seen yet, added to it. The map is asked for those
/// only: on a revisit the fixed keyframes' points (up to LocalMapping.MaxFixedKeyFrames of them) are
/// mostly the same few thousand, and each lookup takes a hash probe and a shared_ptr copy.
void newPointIds(const map::KeyFrame& kf, std::unordered_set<map::MapPointId>* point_seen,
                 std::vector<map::MapPointId>* ids) {
  ids->clear();
  for (const map::MapPointId id : kf.mapPoints()) {
    if (id.valid() && point_seen->insert(id).second) ids->push_back(id);
  }
}

/// Points seen by the window's first `window_end` keyframes (beta at least Window.MinPointBeta, each
/// id once in *point_seen), and the other keyframes seeing most of them (fixed). Returns the points.
std::vector<std::shared_ptr<map::MapPoint>> addObservedPoints(map::Map& map, const WindowBaOptions& options,
                                                              std::size_t window_end, Window* window,
                                                              KeyFrameIndex* index_of,
                                                              std::unordered_set<map::MapPointId>* point_seen) {
  std::vector<WindowKeyFrame>& keyframes = window->keyframes;
  std::vector<std::shared_ptr<map::MapPoint>> points;
  std::unordered_map<map::KeyFrameId, int> fixed_counts;
  map::Observations observations;
  std::vector<map::MapPointId> ids;
  std::vector<std::shared_ptr<map::MapPoint>> kf_points;
  for (std::size_t k = 0; k < window_end; ++k) {
    newPointIds(*keyframes[k].kf, point_seen, &ids);
    map.mapPointsInto(ids, &kf_points);
    for (std::size_t i = 0; i < ids.size(); ++i) {
      const std::shared_ptr<map::MapPoint>& point = kf_points[i];
      if (!point || point->isBad() || point->beta() < options.min_point_beta) continue;
      points.push_back(point);
      point->observationsInto(&observations);
      for (const auto& [observer, index] : observations) {
        if (index_of->count(observer) == 0) ++fixed_counts[observer];
      }
    }
  }
  std::vector<std::pair<int, map::KeyFrameId>> by_count;
  for (const auto& [id, count] : fixed_counts) by_count.emplace_back(-count, id);
  std::sort(by_count.begin(), by_count.end());
  for (const auto& [negative_count, id] : by_count) {
    if (keyframes.size() - window_end >= options.max_fixed_keyframes) break;
    const std::shared_ptr<map::KeyFrame> other = map.keyFrame(id);
    if (usable(other)) addKeyFrame(other, true, window, index_of);
  }
  // Gauge: without any fixed keyframe, hold the oldest of the window.
  if (std::none_of(keyframes.begin(), keyframes.end(), [](const WindowKeyFrame& e) { return e.fixed; })) {
    std::min_element(keyframes.begin(), keyframes.end(), [](const WindowKeyFrame& a, const WindowKeyFrame& b) {
      return a.kf->t_s() < b.kf->t_s();
    })->fixed = true;
  }
  return points;
}

/// The problem's camera model (kf's), gravity, weights and the keyframe states.
void setUpProblem(const map::KeyFrame& kf, const WindowBaOptions& options, Window* window) {
  optim::LocalBaProblem& problem = window->problem;
  problem.model.camera = kf.camera();
  problem.model.T_c_x = kf.T_b_c().inverse();
  problem.model.bf_px_m = options.bf_px_m;
  problem.g_w = options.g_w;
  problem.lambda_imu = options.lambda_imu;
  problem.held_acc_bias_sigma_m_s2 = options.held_acc_bias_sigma_m_s2;
  for (const WindowKeyFrame& entry : window->keyframes) {
    optim::BaKeyFrame ba;
    ba.id = baId(entry.kf->id());
    ba.T_w_b = entry.kf->T_w_b();
    ba.v_w_b = entry.kf->v_w_b();
    ba.bias = entry.kf->bias();
    ba.fixed = entry.fixed;
    ba.velocity_free = entry.fixed && entry.velocity_free;
    ba.velocity_prior_sigma_m_s = entry.velocity_prior_sigma_m_s;
    ba.velocity_prior = entry.velocity_prior;
    problem.keyframes.push_back(ba);
  }
}

/// `point` with its observations by the window's keyframes into the problem, unless they leave it
/// unconstrained. Of its observations by the fixed observers (window keyframes from `window_end`
/// on, ordered by the points they share with the window), at most `max_fixed_observations` (0: all)
/// enter, the first in that order. *point_observations_buffer is scratch space, reused across points.
void addPoint(const std::shared_ptr<map::MapPoint>& point, const KeyFrameIndex& index_of,
              const std::vector<float>& level_sigma2, std::size_t window_end, std::size_t max_fixed_observations,
              map::Observations* point_observations_buffer, Window* window) {
  optim::LocalBaProblem& problem = window->problem;
  const std::size_t point_index = window->points.size();
  const double beta = point->beta();
  std::vector<optim::BaObservation> observations;
  std::vector<ObservationRef> point_refs;
  bool has_depth = false;
  point->observationsInto(point_observations_buffer);
  const map::Observations& point_observations = *point_observations_buffer;
  // The window index below which a fixed observer's observation is kept (all when uncapped).
  std::size_t fixed_index_limit = window->keyframes.size();
  if (max_fixed_observations > 0) {
    std::vector<std::size_t> fixed_indices;
    for (const auto& [observer, index] : point_observations) {
      const auto it = index_of.find(observer);
      if (it != index_of.end() && it->second >= window_end) fixed_indices.push_back(it->second);
    }
    if (fixed_indices.size() > max_fixed_observations) {
      std::nth_element(fixed_indices.begin(), fixed_indices.begin() + static_cast<long>(max_fixed_observations),
                       fixed_indices.end());
      fixed_index_limit = fixed_indices[max_fixed_observations];
    }
  }
  for (const auto& [observer, index] : point_observations) {
    const auto it = index_of.find(observer);
    if (it == index_of.end() || it->second >= fixed_index_limit) continue;
    const WindowKeyFrame& entry = window->keyframes[it->second];
    if (index < 0 || index >= entry.kf->numKeypoints()) continue;
    const features::Keypoint& kp = entry.kf->keypoints()[static_cast<std::size_t>(index)];
    optim::BaObservation obs;
    obs.keyframe_id = baId(observer);
    obs.point_id = baId(point->id());
    obs.uv = Vec2(kp.x_px, kp.y_px);
    obs.depth_m = entry.kf->depth_m(index);
    obs.sigma_px = std::sqrt(static_cast<double>(
        level_sigma2[std::min<std::size_t>(static_cast<std::size_t>(kp.octave), level_sigma2.size() - 1)]));
    obs.static_weight = beta * gammaOfKeypoint(entry, index);
    has_depth = has_depth || obs.depth_m > 0.0;
    observations.push_back(obs);
    point_refs.push_back({it->second, point_index, index});
  }
  // A point needs depth or two views to be constrained.
  if (observations.empty() || (!has_depth && observations.size() < 2)) return;
  problem.points.push_back({baId(point->id()), point->p_w()});
  window->points.push_back(point);
  window->visibility.push_back(visibilityOf(*point));
  window->sole_observer.push_back(point->numObservations() == 1 && point_refs.size() == 1
                                      ? static_cast<int>(point_refs.front().keyframe)
                                      : -1);
  problem.observations.insert(problem.observations.end(), observations.begin(), observations.end());
  for (const ObservationRef& ref : point_refs) {
    if (ref.keyframe >= window_end) ++window->fixed_observations;
  }
  window->refs.insert(window->refs.end(), point_refs.begin(), point_refs.end());
}

/// LocalMapping.MaxFixedObservationRatio: the largest per-point limit on the observations from fixed
/// keyframes (window keyframes from `window_end` on) under which `points` keep at most `ratio` times
/// as many of them as the optimised keyframes make (window keyframes before `window_end`), at least 1;
/// 0 when all of them fit (or the ratio is 0).
std::size_t fixedObservationLimit(const std::vector<std::shared_ptr<map::MapPoint>>& points,
                                  const KeyFrameIndex& index_of, std::size_t window_end, double ratio) {
  if (ratio <= 0.0) return 0;
  // points_with_more[m]: the points with more than m fixed observers. Limit n keeps
  // sum over p of min(count_p, n) = sum over m < n of points_with_more[m].
  std::vector<std::size_t> points_with_more;
  std::size_t fixed_total = 0, window_total = 0;
  map::Observations observations;
  for (const std::shared_ptr<map::MapPoint>& point : points) {
    std::size_t count = 0;
    point->observationsInto(&observations);
    for (const auto& [observer, index] : observations) {
      const auto it = index_of.find(observer);
      if (it == index_of.end()) continue;
      if (it->second >= window_end) {
        ++count;
      } else {
        ++window_total;
      }
    }
    if (count > points_with_more.size()) points_with_more.resize(count, 0);
    for (std::size_t m = 0; m < count; ++m) ++points_with_more[m];
    fixed_total += count;
  }
  const double budget = ratio * static_cast<double>(window_total);
  if (static_cast<double>(fixed_total) <= budget) return 0;
  std::size_t kept = 0;
  for (std::size_t limit = 0; limit < points_with_more.size(); ++limit) {
    kept += points_with_more[limit];
    if (static_cast<double>(kept) > budget) return std::max<std::size_t>(limit, 1);
  }
  return 0;
}

/// Probe points for Eq. 56: the static points of the fixed keyframes (from `window_end` on) the
/// window does not see (a dynamic object may hide them from the window's keyframes); at most
/// LocalMapping.MaxProbePointRatio times the window's points, an even stride through them in the
/// fixed keyframes' order (those sharing most points with the window first) when more. The ids are
/// thinned before the map is asked for the points.
void addProbePoints(map::Map& map, const WindowBaOptions& options, std::size_t window_end,
                    std::unordered_set<map::MapPointId>* point_seen, Window* window) {
  const std::vector<WindowKeyFrame>& keyframes = window->keyframes;
  std::vector<map::MapPointId> ids;
  std::vector<map::MapPointId> kf_ids;
  for (std::size_t k = window_end; k < keyframes.size(); ++k) {
    newPointIds(*keyframes[k].kf, point_seen, &kf_ids);
    ids.insert(ids.end(), kf_ids.begin(), kf_ids.end());
  }
  if (options.max_probe_point_ratio > 0.0) {
    const auto cap =
        static_cast<std::size_t>(options.max_probe_point_ratio * static_cast<double>(window->points.size()));
    if (ids.size() > cap) {
      // ids[floor(i n / cap)] for i < cap: increasing, so the thinning can run in place.
      const std::size_t n = ids.size();
      for (std::size_t i = 0; i < cap; ++i) ids[i] = ids[i * n / cap];
      ids.resize(cap);
    }
  }
  std::vector<std::shared_ptr<map::MapPoint>> points;
  map.mapPointsInto(ids, &points);
  for (const std::shared_ptr<map::MapPoint>& point : points) {
    if (!point || point->isBad()) continue;
    const double beta = point->beta();
    if (beta < options.min_point_beta) continue;
    window->probes.push_back({point->p_w(), beta, visibilityOf(*point)});
  }
}

Window collectWindow(map::Map& map, const std::shared_ptr<map::KeyFrame>& kf, const WindowBaOptions& options,
                     const std::vector<float>& level_sigma2) {
  Window window;
  KeyFrameIndex index_of;
  // ---- the optimised window (and, inertial, the fixed keyframe before it) ----
  addOptimisedKeyFrames(map, kf, options, &window, &index_of);
  const std::size_t window_end = window.keyframes.size();
  // ---- points seen by the window, and the other keyframes seeing them (fixed) ----
  std::unordered_set<map::MapPointId> point_seen;
  const std::vector<std::shared_ptr<map::MapPoint>> points =
      addObservedPoints(map, options, window_end, &window, &index_of, &point_seen);
  // ---- the problem ----
  setUpProblem(*kf, options, &window);
  std::size_t limit = options.max_fixed_observations_per_point;
  const std::size_t ratio_limit =
      fixedObservationLimit(points, index_of, window_end, options.max_fixed_observation_ratio);
  if (ratio_limit > 0 && (limit == 0 || ratio_limit < limit)) limit = ratio_limit;
  window.fixed_observation_limit = limit;
  map::Observations observations;
  for (const std::shared_ptr<map::MapPoint>& point : points) {
    addPoint(point, index_of, level_sigma2, window_end, limit, &observations, &window);
  }
  if (options.robust) addProbePoints(map, options, window_end, &point_seen, &window);
  return window;
}

/// Poses (and, with an inertial link, velocities and biases) and point positions back to the map.
void writeStates(const Window& window, const optim::LocalBaResult& result) {
  std::unordered_set<int> with_inertial;
  for (const optim::BaInertialLink& link : window.problem.inertial) {
    with_inertial.insert(link.keyframe_i);
    with_inertial.insert(link.keyframe_j);
  }
  for (std::size_t k = 0; k < window.keyframes.size(); ++k) {
    const WindowKeyFrame& entry = window.keyframes[k];
    if (entry.kf->isBad()) continue;
    const optim::BaKeyFrame& out = result.keyframes[k];
    if (entry.fixed) {
      if (entry.velocity_free && with_inertial.count(out.id) > 0 && out.v_w_b.allFinite()) {
        entry.kf->setVelocity(out.v_w_b);
      }
      continue;
    }
    if (!out.T_w_b.translation().allFinite()) continue;
    entry.kf->setPose_T_w_b(out.T_w_b);
    if (with_inertial.count(out.id) > 0) {
      entry.kf->setVelocity(out.v_w_b);
      entry.kf->setBias(out.bias);
    }
  }
  for (std::size_t m = 0; m < window.points.size(); ++m) {
    if (!window.points[m]->isBad() && result.points[m].p_w.allFinite()) window.points[m]->setPosition(result.points[m].p_w);
  }
}

/// Erases the observations failing the chi2 gate (or behind the camera) of points still in the map;
/// a point left without observations goes too. Returns the number erased.
int eraseOutlierObservations(map::Map& map, const Window& window, const std::vector<bool>& inliers) {
  int erased = 0;
  for (std::size_t o = 0; o < window.refs.size(); ++o) {
    if (inliers[o]) continue;
    const ObservationRef& ref = window.refs[o];
    map::KeyFrame& observer = *window.keyframes[ref.keyframe].kf;
    const std::shared_ptr<map::MapPoint>& point = window.points[ref.point];
    if (point->isBad() || observer.isBad() || observer.mapPoint(ref.index) != point->id()) continue;
    map.eraseObservation(observer, ref.index);
    ++erased;
    if (point->numObservations() == 0) map.eraseMapPoint(point->id());
  }
  return erased;
}

// ---- robust VIBA: the Gamma/B problem of the window ----------------------------------------------

/// The static-score problem of a window: clusters of its optimised keyframes, and for every BA
/// observation either its score observation (optimised keyframe) or the fixed gamma it is
/// weighted with (fixed keyframe).
struct ScoreLayout {
  StaticScoreProblem problem;                ///< observations' r_sq and depth samples filled per round
  std::vector<int> cluster_offset;           ///< per window keyframe; -1 for fixed keyframes
  std::vector<int> score_observation;        ///< per BA observation; -1 from a fixed keyframe
  std::vector<double> fixed_gamma;           ///< per BA observation from a fixed keyframe
  std::vector<bool> point_scored;            ///< per point: has a score observation
};

ScoreLayout scoreLayout(const Window& window) {
  ScoreLayout layout;
  StaticScoreProblem& problem = layout.problem;
  problem.num_points = static_cast<int>(window.points.size());
  layout.cluster_offset.assign(window.keyframes.size(), -1);
  for (std::size_t k = 0; k < window.keyframes.size(); ++k) {
    const WindowKeyFrame& entry = window.keyframes[k];
    if (entry.fixed) continue;
    const map::ClusterSegmentation& layout_k = entry.kf->segmentationLayout();
    const int offset = static_cast<int>(problem.clusters.size());
    layout.cluster_offset[k] = offset;
    const int no_depth = layout_k.noDepthCluster();
    for (std::size_t c = 0; c < entry.gamma.size(); ++c) {
      ScoreCluster cluster;
      cluster.keyframe = static_cast<int>(k);
      // The no-depth cluster keeps gamma = 1; a label-free segmentation has no clusters to refine.
      cluster.fixed = layout_k.labels.empty() || static_cast<int>(c) == no_depth;
      cluster.prior_without_samples = entry.gamma[c];
      problem.clusters.push_back(cluster);
    }
    for (const auto& [a, b] : layout_k.neighbours) {
      if (a < static_cast<int>(entry.gamma.size()) && b < static_cast<int>(entry.gamma.size())) {
        problem.neighbours.emplace_back(offset + a, offset + b);
      }
    }
  }
  layout.score_observation.assign(window.refs.size(), -1);
  layout.fixed_gamma.assign(window.refs.size(), 1.0);
  layout.point_scored.assign(window.points.size(), false);
  for (std::size_t o = 0; o < window.refs.size(); ++o) {
    const ObservationRef& ref = window.refs[o];
    const WindowKeyFrame& entry = window.keyframes[ref.keyframe];
    const int offset = layout.cluster_offset[ref.keyframe];
    if (offset < 0) {
      layout.fixed_gamma[o] = gammaOfKeypoint(entry, ref.index);
      continue;
    }
    const int cluster = entry.kf->clusterOf(ref.index);
    if (cluster < 0 || cluster >= static_cast<int>(entry.gamma.size())) continue;  // weight beta alone
    layout.score_observation[o] = static_cast<int>(problem.observations.size());
    problem.observations.push_back({static_cast<int>(ref.point), offset + cluster, 0.0});
    layout.point_scored[ref.point] = true;
  }
  return layout;
}

/// Eq. 56's depth samples: every window point projected into every optimised keyframe with a depth
/// image, at the current estimates.
std::vector<DepthSample> depthSamples(const Window& window, const ScoreLayout& layout, const optim::LocalBaGraph& graph) {
  std::vector<DepthSample> samples;
  std::vector<Vec3> points_w(window.points.size());
  for (std::size_t m = 0; m < window.points.size(); ++m) points_w[m] = graph.p_w(m);
  for (std::size_t k = 0; k < window.keyframes.size(); ++k) {
    const int offset = layout.cluster_offset[k];
    const map::KeyFrame& kf = *window.keyframes[k].kf;
    const map::ClusterSegmentation& segmentation = kf.segmentationLayout();
    if (offset < 0 || segmentation.labels.empty() || segmentation.depth_mm.empty()) continue;
    const SE3 T_w_c = graph.T_w_b(k) * kf.T_b_c();
    const SE3 T_c_w = T_w_c.inverse();
    const Vec3 centre_w = T_w_c.translation();
    const PinholeCamera& camera = kf.camera();
    const int no_depth = segmentation.noDepthCluster();
    // Cluster and depth disagreement where p_w projects; false when it does not land on depth.
    auto sample = [&](const Vec3& p_w, const Visibility& visibility, DepthSample* out) {
      const Vec3 p_c = T_c_w * p_w;
      if (p_c.z() < kMinProjectionDepth_m) return false;
      const Vec2 uv = camera.project(p_c);
      if (!camera.isInImage(uv) || !expectedVisible(visibility, p_w, centre_w)) return false;
      const double image_depth_m = segmentation.depthAt_m(uv.x(), uv.y());
      if (image_depth_m <= 0.0) return false;
      const int cluster = segmentation.clusterAt(static_cast<float>(uv.x()), static_cast<float>(uv.y()));
      if (cluster == no_depth) return false;
      out->cluster = offset + cluster;
      out->disagreement_m = depthDisagreement_m(p_c.z(), image_depth_m);
      return true;
    };
    DepthSample s;
    for (std::size_t m = 0; m < points_w.size(); ++m) {
      if (window.sole_observer[m] == static_cast<int>(k)) continue;
      s.point = static_cast<int>(m);
      if (sample(points_w[m], window.visibility[m], &s)) samples.push_back(s);
    }
    for (const ProbePoint& probe : window.probes) {
      s.point = -1;
      s.probe_beta = probe.beta;
      if (sample(probe.p_w, probe.visibility, &s)) samples.push_back(s);
    }
  }
  return samples;
}

/// w = beta * gamma of every BA observation from the current scores.
std::vector<double> staticWeights(const Window& window, const ScoreLayout& layout, const StaticScores& scores) {
  std::vector<double> weights(window.refs.size());
  for (std::size_t o = 0; o < window.refs.size(); ++o) {
    const double beta = scores.beta[window.refs[o].point];
    const int s = layout.score_observation[o];
    const double gamma = s >= 0 ? scores.gamma[static_cast<std::size_t>(layout.problem.observations[static_cast<std::size_t>(s)].cluster)]
                                : layout.fixed_gamma[o];
    weights[o] = beta * gamma;
  }
  return weights;
}

/// Writes beta to the scored points, Gamma to the optimised keyframes with clusters, deletes the
/// points that ended dynamic. Fills the stats' static_set_changed and dynamic_points_erased.
void writeScores(map::Map& map, const Window& window, const ScoreLayout& layout, const StaticScores& scores,
                 const WindowBaOptions& options, WindowBaStats& stats) {
  for (std::size_t k = 0; k < window.keyframes.size(); ++k) {
    const int offset = layout.cluster_offset[k];
    const WindowKeyFrame& entry = window.keyframes[k];
    if (offset < 0 || entry.kf->isBad() || entry.kf->segmentationLayout().labels.empty()) continue;
    std::vector<double> gamma(scores.gamma.begin() + offset, scores.gamma.begin() + offset + static_cast<long>(entry.gamma.size()));
    if (gamma == entry.gamma) continue;
    const std::vector<int> static_before = entry.kf->staticKeypoints();
    entry.kf->setGamma(std::move(gamma));
    if (entry.kf->staticKeypoints() != static_before) stats.static_set_changed.push_back(entry.kf);
  }
  for (std::size_t m = 0; m < window.points.size(); ++m) {
    const std::shared_ptr<map::MapPoint>& point = window.points[m];
    if (!layout.point_scored[m] || point->isBad()) continue;
    point->setBeta(scores.beta[m]);
    if (scores.beta[m] < options.min_point_beta && map.eraseMapPoint(point->id())) ++stats.dynamic_points_erased;
  }
}

/// The robust VIBA on a collected window (header comment).
void robustWindowBundleAdjust(map::Map& map, const Window& window, const WindowBaOptions& options,
                              WindowBaStats& stats) {
  optim::LocalBaOptions ba_options;
  ba_options.num_threads = options.num_threads;
  ba_options.stop_flag = options.stop_flag;
  ba_options.chi2_3d = options.huber_chi2;
  optim::LocalBaGraph graph(window.problem, ba_options);
  ScoreLayout layout = scoreLayout(window);

  StaticScores scores;
  scores.beta.reserve(window.points.size());
  for (const std::shared_ptr<map::MapPoint>& point : window.points) scores.beta.push_back(point->beta());
  scores.gamma.resize(layout.problem.clusters.size());
  for (std::size_t c = 0; c < scores.gamma.size(); ++c) scores.gamma[c] = layout.problem.clusters[c].prior_without_samples;

  // Gamma, B for fixed states and points.
  std::vector<double> r_sq;
  std::vector<bool> in_front;
  const std::vector<bool> fixed_by_layout = [&] {
    std::vector<bool> fixed(layout.problem.clusters.size());
    for (std::size_t c = 0; c < fixed.size(); ++c) fixed[c] = layout.problem.clusters[c].fixed;
    return fixed;
  }();
  std::vector<int> window_observations(window.points.size(), 0);
  for (const ObservationRef& ref : window.refs) ++window_observations[ref.point];
  std::vector<bool> cluster_evidence;
  // Only the optimised keyframes' residuals enter the scores (a revisit's window has about as many
  // observations from fixed keyframes).
  std::vector<bool> scored(window.refs.size(), false);
  for (std::size_t o = 0; o < scored.size(); ++o) scored[o] = layout.score_observation[o] >= 0;
  auto score_step = [&] {
    graph.residuals(scored, &r_sq, &in_front);
    for (std::size_t o = 0; o < r_sq.size(); ++o) {
      const int s = layout.score_observation[o];
      if (s >= 0) layout.problem.observations[static_cast<std::size_t>(s)].r_sq = in_front[o] ? r_sq[o] : kBehindCameraRsq;
    }
    layout.problem.depth_samples = depthSamples(window, layout, graph);
    if (options.evidence_only) {
      // The window's evidence on a cluster is Eq. 56's depth samples and the reprojection residuals
      // of points seen from two or more of its keyframes. A cluster without either (typically
      // revealed behind an occluder, its points made from this keyframe's depth) keeps the score
      // tracking gave it: Eq. 54's smoothness alone would pull it halfway to a dynamic neighbour
      // and Eq. 57 would then delete every point it holds.
      cluster_evidence.assign(layout.problem.clusters.size(), false);
      for (const DepthSample& sample : layout.problem.depth_samples) cluster_evidence[static_cast<std::size_t>(sample.cluster)] = true;
      for (const ScoreObservation& o : layout.problem.observations) {
        if (window_observations[static_cast<std::size_t>(o.point)] >= 2) cluster_evidence[static_cast<std::size_t>(o.cluster)] = true;
      }
      for (std::size_t c = 0; c < cluster_evidence.size(); ++c) {
        layout.problem.clusters[c].fixed = fixed_by_layout[c] || !cluster_evidence[c];
      }
    }
    const std::vector<double> beta_before = options.evidence_only ? scores.beta : std::vector<double>();
    scores = solveStaticScores(layout.problem, options.scores, std::move(scores), &stats.c_hat);
    if (options.evidence_only) {
      // Likewise a point seen once, from a cluster without evidence, keeps its beta.
      for (const ScoreObservation& o : layout.problem.observations) {
        const auto m = static_cast<std::size_t>(o.point);
        if (window_observations[m] < 2 && !cluster_evidence[static_cast<std::size_t>(o.cluster)]) scores.beta[m] = beta_before[m];
      }
    }
    ++stats.score_steps;
  };
  // The scores first, at the states tracking left: a dynamic object's depth disagreement with the
  // map (Eq. 56) holds at any nearby pose, so the first state step already leaves it out instead
  // of settling between it and the static world when it holds most of the features.
  score_step();
  sparse_opt::Summary summary;
  for (int round = 0; round < options.alternations; ++round) {
    // States and points for fixed Gamma, B.
    graph.setStaticWeights(staticWeights(window, layout, scores));
    summary = graph.optimize(options.iterations);
    stats.solver_iterations += summary.iterations;
    // A new keyframe waits: stop after this round's score step (it costs a few ms), so B and Gamma
    // follow the states however busy the mapper is.
    stats.aborted = options.stop_flag != nullptr && options.stop_flag->load();
    score_step();
    if (stats.aborted) break;
  }
  const optim::LocalBaResult result = graph.result(summary);
  stats.final_chi2 = summary.final_chi2;
  writeStates(window, result);
  writeScores(map, window, layout, scores, options, stats);
  stats.outliers_erased = eraseOutlierObservations(map, window, result.inliers);
}

}  // namespace

WindowBaStats localWindowBundleAdjust(map::Map& map, const std::shared_ptr<map::KeyFrame>& kf,
                                      const WindowBaOptions& options, const std::vector<float>& level_sigma2) {
  WindowBaStats stats;
  if (!usable(kf)) return stats;
  const Window window = collectWindow(map, kf, options, level_sigma2);
  stats.points = static_cast<int>(window.problem.points.size());
  stats.observations = static_cast<int>(window.problem.observations.size());
  stats.fixed_observations = window.fixed_observations;
  stats.fixed_observation_limit = static_cast<int>(window.fixed_observation_limit);
  stats.inertial_links = static_cast<int>(window.problem.inertial.size());
  stats.probe_points = static_cast<int>(window.probes.size());
  for (const WindowKeyFrame& entry : window.keyframes) (entry.fixed ? stats.fixed_keyframes : stats.optimised_keyframes)++;
  if (stats.optimised_keyframes == 0 || window.problem.observations.empty()) return stats;

  if (options.robust) {
    robustWindowBundleAdjust(map, window, options, stats);
    return stats;
  }
  optim::LocalBaOptions ba_options;
  ba_options.iterations = options.iterations;
  ba_options.num_threads = options.num_threads;
  ba_options.stop_flag = options.stop_flag;
  ba_options.chi2_3d = options.huber_chi2;
  const optim::LocalBaResult result = optim::localBundleAdjust(window.problem, ba_options);
  stats.aborted = options.stop_flag != nullptr && options.stop_flag->load();
  stats.final_chi2 = result.summary.final_chi2;
  stats.solver_iterations = result.summary.iterations;
  writeStates(window, result);
  stats.outliers_erased = eraseOutlierObservations(map, window, result.inliers);
  return stats;
}

}  // namespace ltlo::mapping
