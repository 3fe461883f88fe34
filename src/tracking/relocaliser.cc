#include "ltlo/tracking/relocaliser.h"

#include <cmath>
#include <unordered_set>

#include "ltlo/core/log.h"
#include "ltlo/features/matching.h"
#include "ltlo/place/se3_ransac.h"

namespace ltlo::tracking {

std::vector<RelocalisationHypothesis> relocalisationHypotheses(const map::Frame& frame, const map::Map& map,
                                                               const map::KeyFrameDatabase& database,
                                                               const RelocalisationOptions& options) {
  std::vector<RelocalisationHypothesis> out;
  if (!frame.hasBow()) return out;
  const std::vector<map::PlaceCandidate> candidates =
      database.detectRelocalisationCandidates(frame, map.id(), map::PlaceQueryOptions());
  features::GuidedMatchOptions matching;
  matching.max_distance = options.max_descriptor_distance;
  matching.ratio = options.ratio;
  int tried = 0;
  for (const map::PlaceCandidate& candidate : candidates) {
    if (tried >= options.max_candidates) break;
    const std::shared_ptr<map::KeyFrame>& kf = candidate.keyframe;
    if (!kf || kf->isBad() || !kf->hasBow()) continue;
    ++tried;
    features::OrbFeatures kf_features;
    kf_features.keypoints = kf->keypoints();
    kf_features.descriptors = kf->descriptors();
    const std::vector<features::Match> matches =
        features::matchByBow(frame.featureVector(), frame.features(), kf->featureVector(), kf_features, matching);
    // 3-D-3-D correspondences p_c (frame, from depth) ~ T_c_w * p_w (map point).
    std::vector<place::Correspondence3d> correspondences;
    std::vector<std::pair<int, map::MapPointId>> matched;
    std::unordered_set<map::MapPointId> used;
    for (const features::Match& m : matches) {
      const float depth = frame.depth_m(m.query);
      if (depth <= 0.0f) continue;
      const map::MapPointId id = kf->mapPoint(m.train);
      if (!id.valid() || used.count(id) > 0) continue;
      const std::shared_ptr<map::MapPoint> point = map.mapPoint(id);
      if (!point || point->isBad()) continue;
      used.insert(id);
      place::Correspondence3d c;
      c.p_a = frame.p_c(m.query);
      c.p_b = point->p_w();
      c.sigma_m = std::sqrt(2.0) * place::depthSigma_m(depth);  // the point's depth noise is similar
      correspondences.push_back(c);
      matched.emplace_back(m.query, id);
    }
    if (static_cast<int>(correspondences.size()) < options.min_ransac_inliers) {
      log::debug("relocalisation: keyframe ", kf->id(), ": ", correspondences.size(), " 3-D matches");
      continue;
    }
    place::Se3RansacOptions ransac_options;
    ransac_options.min_inliers = options.min_ransac_inliers;
    ransac_options.seed = static_cast<std::uint32_t>(kf->id().value * 7919u + 17u);
    const place::Se3RansacResult ransac = place::estimateSe3Ransac(correspondences, ransac_options);
    log::debug("relocalisation: keyframe ", kf->id(), ": ", correspondences.size(), " 3-D matches, ",
               ransac.num_inliers, " RANSAC inliers");
    if (!ransac.success) continue;
    RelocalisationHypothesis hypothesis;
    hypothesis.keyframe = kf->id();
    hypothesis.T_w_c = ransac.T_a_b.inverse();  // T_a_b = T_c_w
    hypothesis.correspondences = static_cast<int>(correspondences.size());
    for (std::size_t k = 0; k < matched.size(); ++k) {
      if (ransac.inliers[k]) hypothesis.matches.push_back(matched[k]);
    }
    out.push_back(std::move(hypothesis));
  }
  return out;
}

}  // namespace ltlo::tracking
