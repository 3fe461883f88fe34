#pragma once
/// The run state of the atlas file (format version 2: the optional section "run", atlas_file.h):
/// what a run resumed from the file needs beyond its maps to go on exactly as the saved run would
/// have at its next frame (issue 31). Each stage writes and reads its own part beside its type
/// (Tracker::writeState, LocalMapper::writeState, LoopCloser::writeState, the segmenter's and the
/// run recorder's); system/run_state.h puts them in order. This header is the map layer's share:
///   - the records the parts use: whole frames, IMU preintegrations and samples, small matrices;
///   - the keyframes the parts hold: by id, culled ones included (KeyFrameRefs, RunKeyFrames);
///   - the atlas's own part (AtlasRunState), first in the section:
///       header     the next frame's index in the sequence, the last frame's time
///       ids        the id counters (culled and merged objects' ids are never issued again)
///       maps       every map's version (tracking compares it), the maps merged away (empty, with
///                  their origin and target: Atlas::resolve and the rejoin's origin chain follow them)
///       database   the keyframe database's order (ties between equal BoW scores follow it)
///       flags      anchor keyframes (Loop.HoldLoadedMap), keyframes made at rest
///       culled     culled keyframes a part refers to: map, time, state, culled parent and the pose
///                  relative to it (map::latestPose_T_w_b follows them)
///   then the stages' parts, opaque here.
/// Readers check every count against the bytes left before allocating and every id against the
/// atlas, and fail with AtlasFileError naming the file, the section "run" and the byte offset.
#include <cstdint>
#include <memory>
#include <optional>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/imu_sample.h"
#include "ltlo/core/lie.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/binary_io.h"
#include "ltlo/map/frame.h"
#include "ltlo/map/ids.h"
#include "ltlo/map/map.h"

namespace bow {
class Vocabulary;
}

namespace ltlo::map {

// ---- records ----

/// An IMU preintegration as its bias, noise, end shifts and raw steps; read back by integrating the
/// steps again (the same state bit for bit, see Preintegrated::steps).
void writePreintegration(const imu::Preintegrated& preintegration, ByteWriter& out);
imu::Preintegrated readPreintegration(ByteReader& in);
void writeOptionalPreintegration(const std::optional<imu::Preintegrated>& preintegration, ByteWriter& out);
std::optional<imu::Preintegrated> readOptionalPreintegration(ByteReader& in);
/// Raw IMU samples (stamps non-decreasing).
void writeImuSamples(const ImuSamples& samples, ByteWriter& out);
ImuSamples readImuSamples(ByteReader& in, const char* what);
/// Every field of a frame: image data, segmentation, state, IMU, tracking's matches. Its keypoint
/// grid, back-projected points and keypoint clusters are rebuilt by the constructor that built them;
/// a frame that had its BoW gets it recomputed with `vocabulary` (when given).
void writeFrame(const Frame& frame, ByteWriter& out);
Frame readFrame(ByteReader& in, const bow::Vocabulary* vocabulary);

template <int Rows, int Cols>
void writeMatrix(const Eigen::Matrix<double, Rows, Cols>& m, ByteWriter& out) {
  for (int k = 0; k < Rows * Cols; ++k) out.f64(m.data()[k]);
}
template <int Rows, int Cols>
Eigen::Matrix<double, Rows, Cols> readMatrix(ByteReader& in, const char* what) {
  Eigen::Matrix<double, Rows, Cols> m;
  for (int k = 0; k < Rows * Cols; ++k) m.data()[k] = in.finiteF64(what);
  return m;
}
void writeOptionalSe3(const std::optional<SE3>& T, ByteWriter& out);
std::optional<SE3> readOptionalSe3(ByteReader& in, const char* what);
void writeBias(const imu::ImuBias& bias, ByteWriter& out);
imu::ImuBias readBias(ByteReader& in, const char* what);

// ---- keyframes held by the stages ----

/// Writing side: a stage writes the keyframes it holds through write(); the culled ones among them
/// (and their culled parents) are collected for the atlas part. Not thread-safe (the saving thread).
class KeyFrameRefs {
 public:
  /// Writes kf's id (the invalid id for null); remembers a culled kf and its culled parents.
  void write(const std::shared_ptr<const KeyFrame>& kf, ByteWriter& out);
  /// The culled keyframes written so far, in the order first met.
  const std::vector<std::shared_ptr<const KeyFrame>>& culled() const { return culled_; }

 private:
  std::vector<std::shared_ptr<const KeyFrame>> culled_;
  std::unordered_set<KeyFrameId> seen_;
};

/// Reading side: the keyframes a stage's part may name, the atlas's and the culled ones restored.
class RunKeyFrames {
 public:
  /// Reads an id written by KeyFrameRefs::write: nullptr for the invalid id, else the keyframe;
  /// an id that names neither an atlas keyframe nor a restored culled one fails.
  std::shared_ptr<KeyFrame> read(ByteReader& in, const char* what) const;
  std::shared_ptr<KeyFrame> find(KeyFrameId id) const;
  void add(std::shared_ptr<KeyFrame> kf);

 private:
  std::unordered_map<KeyFrameId, std::shared_ptr<KeyFrame>> keyframes_;
};

// ---- the atlas's part ----

struct RunStateHeader {
  std::uint64_t next_frame_index = 0;  ///< the sequence index the resumed run starts at
  double last_frame_t_s = 0.0;         ///< time of the saved run's last frame (s)
};

/// The atlas part as read (validated against the loaded atlas, not applied yet).
struct AtlasRunState {
  RunStateHeader header;
  IdSource::Counters next_ids;
  std::vector<std::pair<MapId, std::uint64_t>> map_versions;  ///< every map of the file's atlas
  struct MergedMap {
    MapId id;
    MapId target;  ///< the map it went into (possibly merged on itself)
    std::uint64_t version = 0;
    bool created_keyframe = false;
    std::optional<MapOrigin> origin;
  };
  std::vector<MergedMap> merged;     ///< in merge order
  std::vector<KeyFrameId> database;  ///< in insertion order
  std::vector<KeyFrameId> anchors;   ///< KeyFrame::isAnchor
  std::vector<KeyFrameId> at_rest;   ///< KeyFrame::atRest
  struct CulledKeyFrame {
    KeyFrameId id;
    MapId map;
    KeyFrameId culled_parent;  ///< invalid: none
    SE3 T_parent_this;
    std::optional<Frame> state;  ///< time, camera, T_b_c, pose, velocity, bias (no image data)
  };
  std::vector<CulledKeyFrame> culled;
};

/// Writes the header and the atlas part. `refs` is what the stages' parts were written with (so
/// every culled keyframe they name is here); call with the stages stopped.
void writeAtlasRunState(Atlas& atlas, const RunStateHeader& header, const KeyFrameRefs& refs, ByteWriter& out);
/// Reads the header and the atlas part and checks them against `atlas` (the file's maps).
AtlasRunState readAtlasRunState(ByteReader& in, Atlas& atlas);
/// Applies it to `atlas` before any other thread sees it (ids, versions, merged maps, the database
/// rebuilt in its order, flags) and returns the keyframes the stages' parts may name.
RunKeyFrames applyAtlasRunState(AtlasRunState state, Atlas& atlas);

}  // namespace ltlo::map
