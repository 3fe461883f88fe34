#include "ltlo/map/frame.h"

#include <cmath>

#include "bow/vocabulary.h"
#include "ltlo/core/assert.h"

namespace ltlo::map {

std::vector<float> depthsAtKeypoints(const cv::Mat& depth_m, const std::vector<features::Keypoint>& keypoints) {
  LTLO_ASSERT(depth_m.type() == CV_32F, "depth image must be CV_32F metres, got OpenCV type " << depth_m.type());
  std::vector<float> depths(keypoints.size(), 0.0f);
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    const int col = static_cast<int>(std::lround(keypoints[i].x_px));
    const int row = static_cast<int>(std::lround(keypoints[i].y_px));
    if (col < 0 || row < 0 || col >= depth_m.cols || row >= depth_m.rows) continue;
    const float d = depth_m.at<float>(row, col);
    if (std::isfinite(d) && d > 0.0f) depths[i] = d;
  }
  return depths;
}

Frame::Frame(double t_s, const PinholeCamera& camera, const SE3& T_b_c, features::OrbFeatures features,
             std::vector<float> depth_m, std::vector<float> scale_factors)
    : t_s_(t_s),
      camera_(camera),
      T_b_c_(T_b_c),
      features_(std::move(features)),
      scale_factors_(std::move(scale_factors)),
      depth_m_(std::move(depth_m)) {
  const std::size_t n = features_.keypoints.size();
  LTLO_ASSERT(features_.descriptors.size() == n, features_.descriptors.size()
                                                     << " descriptors for " << n << " keypoints");
  LTLO_ASSERT(depth_m_.size() == n, depth_m_.size() << " depths for " << n << " keypoints");
  LTLO_ASSERT(!scale_factors_.empty(), "a frame needs the pyramid scale factors (at least level 0)");
  p_c_.assign(n, Vec3::Zero());
  for (std::size_t i = 0; i < n; ++i) {
    if (depth_m_[i] > 0.0f) {
      const features::Keypoint& kp = features_.keypoints[i];
      p_c_[i] = camera_.backProject(Vec2(kp.x_px, kp.y_px), depth_m_[i]);
    }
  }
  grid_ = GridIndex(features_.keypoints, camera_.width(), camera_.height());
  setSegmentation(ClusterSegmentation::allStatic());
  map_points.assign(n, MapPointId());
  outliers.assign(n, false);
}

std::vector<int> Frame::featuresInArea(float x_px, float y_px, float radius_px, int min_octave, int max_octave) const {
  return grid_.featuresInArea(features_.keypoints, x_px, y_px, radius_px, min_octave, max_octave);
}
void Frame::featuresInArea(float x_px, float y_px, float radius_px, int min_octave, int max_octave,
                           std::vector<int>* found) const {
  grid_.featuresInArea(features_.keypoints, x_px, y_px, radius_px, min_octave, max_octave, found);
}

void Frame::setSegmentation(ClusterSegmentation segmentation, double static_threshold) {
  segmentation.validate();
  segmentation_ = std::move(segmentation);
  static_threshold_ = static_threshold;
  keypoint_cluster_.resize(features_.keypoints.size());
  for (std::size_t i = 0; i < features_.keypoints.size(); ++i) {
    keypoint_cluster_[i] = segmentation_.clusterAt(features_.keypoints[i].x_px, features_.keypoints[i].y_px);
  }
}

std::vector<int> Frame::staticKeypoints() const {
  std::vector<int> indices;
  for (int i = 0; i < numKeypoints(); ++i) {
    if (isStatic(i)) indices.push_back(i);
  }
  return indices;
}

void Frame::computeBow(const bow::Vocabulary& vocabulary, int feature_depth) {
  const std::vector<int> static_indices = staticKeypoints();
  std::vector<features::Descriptor> static_descriptors;
  static_descriptors.reserve(static_indices.size());
  for (int i : static_indices) static_descriptors.push_back(features_.descriptors[static_cast<std::size_t>(i)]);
  bow_vector_ = bow::BowVector();
  bow::FeatureVector local;
  vocabulary.transform(static_descriptors, &bow_vector_, &local, feature_depth);
  // transform() numbers features by their position among the static ones; map back to keypoints.
  feature_vector_.clear();
  for (auto& [node, positions] : local) {
    std::vector<std::uint32_t>& indices = feature_vector_[node];
    indices.reserve(positions.size());
    for (std::uint32_t position : positions) indices.push_back(static_cast<std::uint32_t>(static_indices[position]));
  }
  has_bow_ = true;
}

const SE3& Frame::T_w_b() const {
  LTLO_ASSERT(T_w_b_.has_value(), "frame at t = " << t_s_ << " s has no pose yet");
  return *T_w_b_;
}

}  // namespace ltlo::map
