#pragma once
/// Frame: the per-image data tracking produces (features, depth, BoW, segmentation, state). Owned by
/// the tracking thread and never shared: a KeyFrame is built as a copy of the parts it needs.
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

#include "bow/bow_vector.h"
#include "ltlo/core/camera.h"
#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/features/orb_extractor.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/cluster_segmentation.h"
#include "ltlo/map/grid_index.h"
#include "ltlo/map/ids.h"

namespace bow {
class Vocabulary;
}

namespace ltlo::map {

/// Default static-score threshold: a cluster (and the keypoints on it) is static when gamma >= it.
inline constexpr double kDefaultStaticThreshold = 0.5;

/// Depth (m) at each keypoint from a metric depth image (CV_32F, metres, 0 or non-finite = none),
/// read at the rounded keypoint position; 0 where there is no valid depth.
std::vector<float> depthsAtKeypoints(const cv::Mat& depth_m, const std::vector<features::Keypoint>& keypoints);

/// One RGB-D(-inertial) image. Not thread-safe; owned by one thread at a time (tracking).
class Frame {
 public:
  /// `depth_m[i]` is the depth of keypoint i in metres (0 = none), `scale_factors` is
  /// OrbExtractor::scaleFactors(). The segmentation starts as one static cluster over the image.
  Frame(double t_s, const PinholeCamera& camera, const SE3& T_b_c, features::OrbFeatures features,
        std::vector<float> depth_m, std::vector<float> scale_factors);

  // ---- per-image data (fixed after construction) ----
  double t_s() const { return t_s_; }
  const PinholeCamera& camera() const { return camera_; }
  const SE3& T_b_c() const { return T_b_c_; }
  int numKeypoints() const { return static_cast<int>(features_.keypoints.size()); }
  const features::OrbFeatures& features() const { return features_; }
  const std::vector<features::Keypoint>& keypoints() const { return features_.keypoints; }
  const std::vector<features::Descriptor>& descriptors() const { return features_.descriptors; }
  const std::vector<float>& scaleFactors() const { return scale_factors_; }
  /// Depth of keypoint i (m); 0 = none.
  float depth_m(int i) const { return depth_m_[static_cast<std::size_t>(i)]; }
  const std::vector<float>& depths_m() const { return depth_m_; }
  /// Back-projected 3-D point of keypoint i in the camera frame (m); zero when there is no depth.
  const Vec3& p_c(int i) const { return p_c_[static_cast<std::size_t>(i)]; }
  const std::vector<Vec3>& points_c() const { return p_c_; }
  /// Keypoints within radius_px of (x_px, y_px), octave in [min_octave, max_octave] (see GridIndex).
  std::vector<int> featuresInArea(float x_px, float y_px, float radius_px, int min_octave = 0,
                                  int max_octave = -1) const;
  /// The same into *found, reusing its capacity (per-frame searches allocate nothing).
  void featuresInArea(float x_px, float y_px, float radius_px, int min_octave, int max_octave,
                      std::vector<int>* found) const;
  const GridIndex& grid() const { return grid_; }

  // ---- segmentation seam ----
  /// Replaces the cluster labels and scores; recomputes the keypoints' clusters.
  void setSegmentation(ClusterSegmentation segmentation, double static_threshold = kDefaultStaticThreshold);
  const ClusterSegmentation& segmentation() const { return segmentation_; }
  double staticThreshold() const { return static_threshold_; }
  int clusterOf(int i) const { return keypoint_cluster_[static_cast<std::size_t>(i)]; }
  const std::vector<int>& keypointClusters() const { return keypoint_cluster_; }
  /// The "static only" filter: gamma of keypoint i's cluster >= staticThreshold().
  bool isStatic(int i) const { return segmentation_.gammaOf(clusterOf(i)) >= static_threshold_; }
  /// Indices of the static keypoints, increasing.
  std::vector<int> staticKeypoints() const;

  // ---- bag of words (static keypoints only) ----
  /// Computes the BoW vector and feature vector from the static keypoints' descriptors (feature
  /// indices refer to this frame's keypoints). Recomputes on every call (after setSegmentation).
  void computeBow(const bow::Vocabulary& vocabulary, int feature_depth = 2);
  bool hasBow() const { return has_bow_; }
  const bow::BowVector& bowVector() const { return bow_vector_; }
  const bow::FeatureVector& featureVector() const { return feature_vector_; }

  // ---- state ----
  bool hasPose() const { return T_w_b_.has_value(); }
  /// Body pose in the world; asserts hasPose().
  const SE3& T_w_b() const;
  SE3 T_w_c() const { return T_w_b() * T_b_c_; }
  void setPose_T_w_b(const SE3& T_w_b) { T_w_b_ = T_w_b; }
  void setPose_T_w_c(const SE3& T_w_c) { T_w_b_ = T_w_c * T_b_c_.inverse(); }
  const Vec3& v_w_b() const { return v_w_b_; }
  void setVelocity(const Vec3& v_w_b) { v_w_b_ = v_w_b; }
  const imu::ImuBias& bias() const { return bias_; }
  void setBias(const imu::ImuBias& bias) { bias_ = bias; }
  /// IMU preintegration from the last keyframe / the last frame to this frame (absent without IMU).
  std::optional<imu::Preintegrated> imu_from_last_keyframe;
  std::optional<imu::Preintegrated> imu_from_last_frame;
  /// The raw IMU samples of the frame interval (stamp order, ends interpolated; empty without IMU),
  /// for the zero-velocity test.
  ImuSamples imu_samples;
  /// Tracking held the frame at rest (zero-velocity update, issue 32); a keyframe made from it
  /// says so (KeyFrame::atRest), local mapping's IMU initialisation from rest looks for it.
  bool at_rest = false;
  /// Set on the frame that starts the run's first map after a wait dead-reckoned by the IMU
  /// (Tracking.PreMapImuPose) once a rest was seen before it: gravity and the gyro bias of that rest,
  /// in the map's world. A keyframe made from it keeps it (KeyFrame::preMapRest) for local mapping's
  /// IMU initialisation (ImuInit.FromPreMapRest). Not saved by the run state.
  std::optional<imu::RestEstimate> pre_map_rest;
  /// Keyframe this frame was tracked against (invalid before the first keyframe).
  KeyFrameId reference_keyframe;

  // ---- associations made by tracking ----
  /// Map point matched to keypoint i (invalid id = none) and whether the match was rejected.
  std::vector<MapPointId> map_points;
  std::vector<bool> outliers;

 private:
  double t_s_;
  PinholeCamera camera_;
  SE3 T_b_c_;
  features::OrbFeatures features_;
  std::vector<float> scale_factors_;
  std::vector<float> depth_m_;
  std::vector<Vec3> p_c_;
  GridIndex grid_;

  ClusterSegmentation segmentation_;
  double static_threshold_ = kDefaultStaticThreshold;
  std::vector<int> keypoint_cluster_;

  bool has_bow_ = false;
  bow::BowVector bow_vector_;
  bow::FeatureVector feature_vector_;

  std::optional<SE3> T_w_b_;
  Vec3 v_w_b_ = Vec3::Zero();
  imu::ImuBias bias_;
};

}  // namespace ltlo::map
