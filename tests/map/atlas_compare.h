#pragma once
// Field-by-field equality of two atlases (the atlas file's round trip): every keyframe, map point,
// map and the atlas, with exact (bit-equal) comparisons of every stored number.
#include <gtest/gtest.h>

#include "ltlo/map/atlas.h"

namespace ltlo::map::test {

inline void expectSameSe3(const SE3& a, const SE3& b, const std::string& what) {
  EXPECT_EQ(a.quaternion().coeffs(), b.quaternion().coeffs()) << what;
  EXPECT_EQ(a.translation(), b.translation()) << what;
}

inline void expectSamePreintegration(const imu::Preintegrated& a, const imu::Preintegrated& b,
                                     const std::string& what) {
  EXPECT_EQ(a.bias().b_g, b.bias().b_g) << what;
  EXPECT_EQ(a.bias().b_a, b.bias().b_a) << what;
  EXPECT_EQ(a.noise().gyro_density, b.noise().gyro_density) << what;
  EXPECT_EQ(a.noise().acc_density, b.noise().acc_density) << what;
  EXPECT_EQ(a.noise().gyro_walk_density, b.noise().gyro_walk_density) << what;
  EXPECT_EQ(a.noise().acc_walk_density, b.noise().acc_walk_density) << what;
  EXPECT_EQ(a.noise().nominal_dt_s, b.noise().nominal_dt_s) << what;
  EXPECT_EQ(a.shiftBegin_s(), b.shiftBegin_s()) << what;
  EXPECT_EQ(a.shiftEnd_s(), b.shiftEnd_s()) << what;
  EXPECT_EQ(a.dt_s(), b.dt_s()) << what;
  ASSERT_EQ(a.numSteps(), b.numSteps()) << what;
  EXPECT_EQ(a.deltaR(), b.deltaR()) << what;
  EXPECT_EQ(a.deltaV(), b.deltaV()) << what;
  EXPECT_EQ(a.deltaP(), b.deltaP()) << what;
  EXPECT_EQ(a.covariance(), b.covariance()) << what;
  EXPECT_EQ(a.d_R_d_b_g(), b.d_R_d_b_g()) << what;
  EXPECT_EQ(a.d_v_d_b_g(), b.d_v_d_b_g()) << what;
  EXPECT_EQ(a.d_v_d_b_a(), b.d_v_d_b_a()) << what;
  EXPECT_EQ(a.d_p_d_b_g(), b.d_p_d_b_g()) << what;
  EXPECT_EQ(a.d_p_d_b_a(), b.d_p_d_b_a()) << what;
  imu::ImuBias other = a.bias();
  other.b_g += Vec3(1e-3, -2e-3, 5e-4);
  other.b_a += Vec3(0.01, 0.02, -0.01);
  EXPECT_EQ(a.correctedDeltaR(other), b.correctedDeltaR(other)) << what;
  EXPECT_EQ(a.correctedDeltaV(other), b.correctedDeltaV(other)) << what;
  EXPECT_EQ(a.correctedDeltaP(other), b.correctedDeltaP(other)) << what;
  for (int k = 0; k < a.numSteps(); ++k) {
    EXPECT_EQ(a.steps()[k].gyro_mean_rad_s, b.steps()[k].gyro_mean_rad_s) << what;
    EXPECT_EQ(a.steps()[k].acc_mean_m_s2, b.steps()[k].acc_mean_m_s2) << what;
    EXPECT_EQ(a.steps()[k].dt_s, b.steps()[k].dt_s) << what;
  }
}

inline bool sameMat(const cv::Mat& a, const cv::Mat& b) {
  if (a.empty() || b.empty()) return a.empty() && b.empty();
  return a.type() == b.type() && a.size() == b.size() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

inline void expectSameSegmentation(const ClusterSegmentation& a, const ClusterSegmentation& b,
                                   const std::string& what) {
  EXPECT_TRUE(sameMat(a.labels, b.labels)) << what;
  EXPECT_EQ(a.scale, b.scale) << what;
  EXPECT_EQ(a.gamma, b.gamma) << what;
  EXPECT_EQ(a.pixel_counts, b.pixel_counts) << what;
  EXPECT_EQ(a.neighbours, b.neighbours) << what;
  EXPECT_TRUE(sameMat(a.depth_mm, b.depth_mm)) << what;
  EXPECT_EQ(a.depth_scale, b.depth_scale) << what;
}

inline void expectSameBow(const KeyFrame& a, const KeyFrame& b, const std::string& what) {
  EXPECT_EQ(a.hasBow(), b.hasBow()) << what;
  const bow::BowVector va = a.bowVector(), vb = b.bowVector();
  EXPECT_EQ(va.entries, vb.entries) << what;
  EXPECT_EQ(a.featureVector(), b.featureVector()) << what;
}

inline void expectSameImageData(const KeyFrame& a, const KeyFrame& b, const std::string& what) {
  EXPECT_EQ(a.t_s(), b.t_s()) << what;
  EXPECT_EQ(a.camera().K(), b.camera().K()) << what;
  EXPECT_EQ(a.camera().width(), b.camera().width()) << what;
  EXPECT_EQ(a.camera().height(), b.camera().height()) << what;
  expectSameSe3(a.T_b_c(), b.T_b_c(), what + " T_b_c");
  ASSERT_EQ(a.numKeypoints(), b.numKeypoints()) << what;
  for (int i = 0; i < a.numKeypoints(); ++i) {
    const features::Keypoint& ka = a.keypoints()[i];
    const features::Keypoint& kb = b.keypoints()[i];
    EXPECT_TRUE(ka.x_px == kb.x_px && ka.y_px == kb.y_px && ka.angle_deg == kb.angle_deg &&
                ka.response == kb.response && ka.octave == kb.octave)
        << what << " keypoint " << i;
    EXPECT_EQ(a.descriptors()[i], b.descriptors()[i]) << what;
    EXPECT_EQ(a.depth_m(i), b.depth_m(i)) << what;
    EXPECT_EQ(a.p_c(i), b.p_c(i)) << what;
  }
  EXPECT_EQ(a.scaleFactors(), b.scaleFactors()) << what;
  EXPECT_EQ(a.keypointClusters(), b.keypointClusters()) << what;
  EXPECT_EQ(a.staticThreshold(), b.staticThreshold()) << what;
  expectSameSegmentation(a.segmentationLayout(), b.segmentationLayout(), what + " layout");
  // The grid: the same keypoints in windows over the image.
  for (float x = 0.0f; x < 640.0f; x += 97.0f) {
    for (float y = 0.0f; y < 480.0f; y += 83.0f)
      EXPECT_EQ(a.featuresInArea(x, y, 40.0f), b.featuresInArea(x, y, 40.0f)) << what;
  }
}

inline void expectSameKeyFrame(const KeyFrame& a, const KeyFrame& b) {
  const std::string what = "keyframe " + std::to_string(a.id().value);
  EXPECT_EQ(a.id(), b.id());
  expectSameImageData(a, b, what);
  EXPECT_EQ(a.gamma(), b.gamma()) << what;
  EXPECT_EQ(a.staticAreaRatio(), b.staticAreaRatio()) << what;
  EXPECT_EQ(a.staticKeypoints(), b.staticKeypoints()) << what;
  expectSameSegmentation(a.segmentation(), b.segmentation(), what + " segmentation");
  expectSameBow(a, b, what);
  EXPECT_EQ(a.mapId(), b.mapId()) << what;
  expectSameSe3(a.T_w_b(), b.T_w_b(), what + " T_w_b");
  EXPECT_EQ(a.v_w_b(), b.v_w_b()) << what;
  EXPECT_EQ(a.bias().b_g, b.bias().b_g) << what;
  EXPECT_EQ(a.bias().b_a, b.bias().b_a) << what;
  EXPECT_EQ(a.previousKeyFrame(), b.previousKeyFrame()) << what;
  EXPECT_EQ(a.nextKeyFrame(), b.nextKeyFrame()) << what;
  ASSERT_EQ(a.imuFromPrevious().has_value(), b.imuFromPrevious().has_value()) << what;
  if (a.imuFromPrevious()) expectSamePreintegration(*a.imuFromPrevious(), *b.imuFromPrevious(), what + " imu");
  EXPECT_EQ(a.mapPoints(), b.mapPoints()) << what;
  EXPECT_EQ(a.numObservations(), b.numObservations()) << what;
  EXPECT_EQ(a.covisibles(), b.covisibles()) << what;
  EXPECT_EQ(a.parent(), b.parent()) << what;
  EXPECT_EQ(a.children(), b.children()) << what;
  EXPECT_EQ(a.loopEdges(), b.loopEdges()) << what;
  EXPECT_EQ(a.isBad(), b.isBad()) << what;
}

inline void expectSameMapPoint(const MapPoint& a, const MapPoint& b) {
  const std::string what = "map point " + std::to_string(a.id().value);
  EXPECT_EQ(a.id(), b.id());
  EXPECT_EQ(a.p_w(), b.p_w()) << what;
  EXPECT_EQ(a.observations(), b.observations()) << what;
  EXPECT_EQ(a.referenceKeyFrame(), b.referenceKeyFrame()) << what;
  EXPECT_EQ(a.descriptor(), b.descriptor()) << what;
  EXPECT_EQ(a.normal_w(), b.normal_w()) << what;
  EXPECT_EQ(a.minDistance_m(), b.minDistance_m()) << what;
  EXPECT_EQ(a.maxDistance_m(), b.maxDistance_m()) << what;
  EXPECT_EQ(a.numVisible(), b.numVisible()) << what;
  EXPECT_EQ(a.numFound(), b.numFound()) << what;
  EXPECT_EQ(a.beta(), b.beta()) << what;
  EXPECT_EQ(a.isBad(), b.isBad()) << what;
  EXPECT_EQ(a.replacedBy(), b.replacedBy()) << what;
}

inline void expectSameMap(const Map& a, const Map& b) {
  const std::string what = "map " + std::to_string(a.id().value);
  EXPECT_EQ(a.id(), b.id());
  EXPECT_EQ(a.originKeyFrames(), b.originKeyFrames()) << what;
  EXPECT_EQ(a.gaugeKeyFrame(), b.gaugeKeyFrame()) << what;
  EXPECT_EQ(a.referenceMapPoints(), b.referenceMapPoints()) << what;
  ASSERT_EQ(a.origin().has_value(), b.origin().has_value()) << what;
  if (const std::optional<MapOrigin> oa = a.origin()) {
    const MapOrigin ob = *b.origin();
    EXPECT_EQ(oa->parent, ob.parent) << what;
    EXPECT_EQ(oa->sigma_position_m, ob.sigma_position_m) << what;
    EXPECT_EQ(oa->sigma_rotation_rad, ob.sigma_rotation_rad) << what;
    EXPECT_EQ(oa->t_s, ob.t_s) << what;
    EXPECT_EQ(oa->parent_keyframe, ob.parent_keyframe) << what;
    EXPECT_EQ(oa->first_keyframe, ob.first_keyframe) << what;
    ASSERT_EQ(oa->imu_across != nullptr, ob.imu_across != nullptr) << what;
    if (oa->imu_across) expectSamePreintegration(*oa->imu_across, *ob.imu_across, what + " imu_across");
    expectSameSe3(oa->T_w_b_parent_keyframe, ob.T_w_b_parent_keyframe, what + " T_w_b_parent_keyframe");
  }
  const std::vector<std::shared_ptr<KeyFrame>> kfs_a = a.keyFrames(), kfs_b = b.keyFrames();
  ASSERT_EQ(kfs_a.size(), kfs_b.size()) << what;
  for (std::size_t k = 0; k < kfs_a.size(); ++k) expectSameKeyFrame(*kfs_a[k], *kfs_b[k]);
  const std::vector<std::shared_ptr<MapPoint>> points_a = a.mapPoints(), points_b = b.mapPoints();
  ASSERT_EQ(points_a.size(), points_b.size()) << what;
  for (std::size_t k = 0; k < points_a.size(); ++k) expectSameMapPoint(*points_a[k], *points_b[k]);
}

inline void expectSameAtlas(Atlas& a, Atlas& b) {
  EXPECT_EQ(a.mapIds(), b.mapIds());
  EXPECT_EQ(a.activeMapId(), b.activeMapId());
  EXPECT_EQ(a.keyFrameDatabase().size(), b.keyFrameDatabase().size());
  const std::vector<MapId> ids = a.mapIds();
  for (const MapId id : ids) {
    ASSERT_NE(b.map(id), nullptr) << id;
    expectSameMap(*a.map(id), *b.map(id));
  }
}

}  // namespace ltlo::map::test
