#pragma once
/// KeyFrame: a Frame promoted into the map. Shared by tracking, local mapping and loop closing
/// (and read by the optimiser); the Map owns it through shared_ptr.
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "ltlo/map/frame.h"
#include "ltlo/map/ids.h"

namespace ltlo::map {

/// Restore-side entry points of the atlas file reader (src/map/atlas_file_access.h).
struct AtlasFileAccess;

/// Covisibility edges weaker than this are dropped when connections are rebuilt (the strongest
/// one is kept even if weaker, so a keyframe with shared points is never disconnected).
inline constexpr int kMinCovisibilityWeight = 15;

/// Thread-safe: the per-image data copied from the Frame is immutable and read without a lock;
/// everything else is guarded by the keyframe's own mutex_ and returned as copies. Lock order
/// (atlas.h): Atlas -> Map -> KeyFrame -> MapPoint; KeyFrame methods take no other lock.
/// Touched by tracking (reads), local mapping (observations, covisibility, culling, BA poses),
/// loop closing (poses, loop edges) and the Atlas (map merging).
class KeyFrame {
 public:
  /// Copies the per-image data and state of `frame` (which must have a pose). `frame`'s map-point
  /// matches become this keyframe's observations only through Map::addObservation.
  KeyFrame(KeyFrameId id, MapId map, const Frame& frame);
  KeyFrame(const KeyFrame&) = delete;
  KeyFrame& operator=(const KeyFrame&) = delete;

  // ---- immutable per-image data (no lock) ----
  KeyFrameId id() const { return id_; }
  double t_s() const { return t_s_; }
  const PinholeCamera& camera() const { return camera_; }
  const SE3& T_b_c() const { return T_b_c_; }
  int numKeypoints() const { return static_cast<int>(features_.keypoints.size()); }
  const std::vector<features::Keypoint>& keypoints() const { return features_.keypoints; }
  const std::vector<features::Descriptor>& descriptors() const { return features_.descriptors; }
  const std::vector<float>& scaleFactors() const { return scale_factors_; }
  float depth_m(int i) const { return depth_m_[static_cast<std::size_t>(i)]; }
  const Vec3& p_c(int i) const { return p_c_[static_cast<std::size_t>(i)]; }
  std::vector<int> featuresInArea(float x_px, float y_px, float radius_px, int min_octave = 0,
                                  int max_octave = -1) const;
  /// The same into *found, reusing its capacity (searches over many points).
  void featuresInArea(float x_px, float y_px, float radius_px, int min_octave, int max_octave,
                      std::vector<int>* found) const;
  /// Cluster of each keypoint (fixed); the scores may change.
  int clusterOf(int i) const { return keypoint_cluster_[static_cast<std::size_t>(i)]; }
  const std::vector<int>& keypointClusters() const { return keypoint_cluster_; }
  double staticThreshold() const { return static_threshold_; }
  /// The fixed parts of the segmentation: labels (8-bit, reduced resolution, see
  /// ClusterSegmentation::scale), pixel counts, V_i and the depth for Eq. 56. gamma in this copy is
  /// the one the keyframe was created with; the current scores are gamma().
  const ClusterSegmentation& segmentationLayout() const { return segmentation_layout_; }

  // ---- bag of words (static keypoints; recomputed by local mapping when Gamma changes) ----
  bool hasBow() const;
  bow::BowVector bowVector() const;
  bow::FeatureVector featureVector() const;
  /// Replaces the BoW (computed by the caller from the keyframe's current static keypoints).
  void setBow(bow::BowVector bow_vector, bow::FeatureVector feature_vector);

  // ---- static scores (Gamma) ----
  std::vector<double> gamma() const;
  /// Replaces Gamma (one score per cluster, size unchanged) and recomputes the static area ratio.
  void setGamma(std::vector<double> gamma);
  bool isStatic(int i) const;
  /// Indices of the static keypoints, increasing (one lock for the whole pass).
  std::vector<int> staticKeypoints() const;
  /// Layout and current scores together (for saving the run's segmentation).
  ClusterSegmentation segmentation() const;
  /// ClusterSegmentation::staticAreaRatio of the current scores (Loop.MinStaticRatio).
  double staticAreaRatio() const;

  // ---- state ----
  MapId mapId() const;
  void setMapId(MapId map);
  SE3 T_w_b() const;
  SE3 T_w_c() const;
  /// Camera centre in the world (m).
  Vec3 cameraCentre_w() const;
  void setPose_T_w_b(const SE3& T_w_b);
  Vec3 v_w_b() const;
  void setVelocity(const Vec3& v_w_b);
  imu::ImuBias bias() const;
  void setBias(const imu::ImuBias& bias);
  /// IMU chain: the previous/next keyframe in time and the preintegration from the previous one.
  KeyFrameId previousKeyFrame() const;
  KeyFrameId nextKeyFrame() const;
  void setPreviousKeyFrame(KeyFrameId id);
  void setNextKeyFrame(KeyFrameId id);
  std::optional<imu::Preintegrated> imuFromPrevious() const;
  /// Of the preintegration from the previous keyframe, without copying it: its span (s) and how
  /// far its end is shifted from this keyframe's stamp (s) (Preintegrated::dt_s, shiftEnd_s).
  struct ImuLinkTiming {
    double dt_s = 0.0;
    double shift_end_s = 0.0;
  };
  std::optional<ImuLinkTiming> imuLinkTiming() const;
  /// Made from a frame tracking held at rest (Frame::at_rest): the IMU link from the previous
  /// keyframe was then a standstill, if the previous keyframe is at rest too or was the map's first.
  bool atRest() const { return at_rest_; }
  /// Gravity and gyro bias of the rest before the run's first map (Frame::pre_map_rest), on that
  /// map's first keyframe only; immutable.
  const std::optional<imu::RestEstimate>& preMapRest() const { return pre_map_rest_; }
  void setImuFromPrevious(std::optional<imu::Preintegrated> preintegration);

  // ---- observations: keypoint index -> map point (written through Map) ----
  MapPointId mapPoint(int i) const;
  std::vector<MapPointId> mapPoints() const;
  /// Number of keypoints with a map point.
  int numObservations() const;

  // ---- covisibility graph (ids; weight = number of shared map points) ----
  /// Covisible keyframes with weights, best first (ties: lower id first).
  std::vector<std::pair<KeyFrameId, int>> covisibles() const;
  std::vector<KeyFrameId> bestCovisibles(std::size_t max_count) const;
  std::vector<KeyFrameId> covisiblesWithWeightAtLeast(int min_weight) const;
  /// Shared-point weight to `other`, 0 when not connected.
  int weight(KeyFrameId other) const;
  /// Sets or updates one edge (no-op on a bad keyframe); weight <= 0 erases it.
  void addConnection(KeyFrameId other, int weight);
  void eraseConnection(KeyFrameId other);

  // ---- spanning tree and loop edges ----
  KeyFrameId parent() const;
  std::vector<KeyFrameId> children() const;
  std::vector<KeyFrameId> loopEdges() const;
  void addLoopEdge(KeyFrameId other);

  bool isBad() const;
  /// An anchor keyframe (a loaded atlas's, Loop.HoldLoadedMap): the world's reference, its pose held
  /// by every optimisation (local and full BAs, the loop correction's essential graph and window,
  /// the seam welding), so a run in a loaded atlas stays in that atlas's world frame. Set once,
  /// before the keyframe is shared with another thread (System, after loading), then read only.
  bool isAnchor() const { return anchor_; }
  void markAnchor() { anchor_ = true; }

  // ---- culling ----
  /// Set by Map::eraseKeyFrame: the spanning-tree parent at culling time (nullptr when it had none)
  /// and this keyframe's body pose relative to it, T_parent_this = T_w_parent^-1 T_w_this. Frames
  /// that used a culled keyframe as reference follow this chain to a live keyframe.
  std::shared_ptr<KeyFrame> culledParent() const;
  SE3 T_parent_this() const;
  /// Points this culled keyframe at `parent`, a stand-in (culledStandIn) of its culled parent, in
  /// place of that parent; T_parent_this stays. Asserts that this keyframe is bad and that `parent`
  /// has the id of its culled parent.
  void replaceCulledParent(std::shared_ptr<KeyFrame> parent);

 private:
  friend class Map;
  friend struct AtlasFileAccess;
  void setCulledParent(std::shared_ptr<KeyFrame> parent, const SE3& T_parent_this);
  /// Map-side writers (Map keeps both ends of each link consistent).
  bool setMapPoint(int i, MapPointId point);    ///< false on a bad keyframe
  void eraseMapPoint(int i, MapPointId point);  ///< only if keypoint i still holds `point`
  void replaceConnections(std::unordered_map<KeyFrameId, int> weights);
  void setParent(KeyFrameId parent);
  bool addChild(KeyFrameId child);  ///< false on a bad keyframe
  void eraseChild(KeyFrameId child);
  bool setBad();  ///< false if it already was bad
  /// Map::eraseKeyFrame: marks the keyframe bad and sets its culled parent in one step, so a reader
  /// that sees it bad sees its parent (culledStandIn); false (nothing changed) if it already was bad.
  bool setCulled(std::shared_ptr<KeyFrame> parent, const SE3& T_parent_this);
  friend std::shared_ptr<KeyFrame> culledStandIn(const KeyFrame& culled);
  void sortCovisiblesLocked();

  // Immutable per-image data.
  const KeyFrameId id_;
  const double t_s_;
  const PinholeCamera camera_;
  const SE3 T_b_c_;
  const features::OrbFeatures features_;
  const std::vector<float> scale_factors_;
  const std::vector<float> depth_m_;
  const std::vector<Vec3> p_c_;
  const GridIndex grid_;
  const ClusterSegmentation segmentation_layout_;
  const std::vector<int> keypoint_cluster_;
  const double static_threshold_;
  bool anchor_ = false;  ///< see isAnchor(); written before the keyframe is shared, no lock
  const std::optional<imu::RestEstimate> pre_map_rest_;

  mutable std::mutex mutex_;  ///< guards every member below
  MapId map_;
  bool has_bow_ = false;
  bow::BowVector bow_vector_;
  bow::FeatureVector feature_vector_;
  std::vector<double> gamma_;
  double static_area_ratio_ = 1.0;
  SE3 T_w_b_;
  Vec3 v_w_b_ = Vec3::Zero();
  imu::ImuBias bias_;
  KeyFrameId previous_;
  KeyFrameId next_;
  std::optional<imu::Preintegrated> imu_from_previous_;
  bool at_rest_ = false;
  std::vector<MapPointId> map_points_;
  std::unordered_map<KeyFrameId, int> connections_;
  std::vector<std::pair<KeyFrameId, int>> ordered_covisibles_;  ///< connections_ sorted best first
  KeyFrameId parent_;
  std::vector<KeyFrameId> children_;
  std::vector<KeyFrameId> loop_edges_;
  bool bad_ = false;
  std::shared_ptr<KeyFrame> culled_parent_;
  SE3 T_parent_this_;
};

/// BoW of the keyframe's current static keypoints, as Frame::computeBow lays it out (feature indices
/// are keypoint indices, direct index at tree depth 2): what local mapping recomputes when Gamma
/// changes and what a loaded atlas rebuilds (KeyFrame::setBow takes it).
std::pair<bow::BowVector, bow::FeatureVector> staticKeypointsBow(const KeyFrame& kf,
                                                                const bow::Vocabulary& vocabulary);

/// A culled keyframe as the holders of a frame's reference need it (latestPose_T_w_b, its id, map,
/// time, camera, T_b_c and state at culling): bad, with the same culled parent and T_parent_this,
/// and without the image data (features, depths, grid, segmentation layout; ~250 KB at VGA), which
/// nobody reads once a keyframe is culled. The run's frame records hold these instead of the culled
/// keyframes (system/run_recorder.h), so a culled keyframe's memory is freed once the stages let go
/// of it. Asserts that `culled` is bad.
std::shared_ptr<KeyFrame> culledStandIn(const KeyFrame& culled);

/// The keyframe's current body pose, also once culled: a culled keyframe's pose is its culled
/// parent's current pose composed with T_parent_this (recursively), so frames referenced to it follow
/// later corrections (loop closure, merge, BA) of the keyframes that remain.
SE3 latestPose_T_w_b(const KeyFrame& kf);

}  // namespace ltlo::map
