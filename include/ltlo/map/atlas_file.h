#pragma once
/// The atlas file: every map of an Atlas with its keyframes, map points and graphs, the run's IMU
/// state and what the atlas was built with, so a later run can load it (issue 31).
///
/// Layout (version 2, little-endian throughout; version 1 is the same without the run section):
///   bytes 0-7    magic "LTLOATL1"
///   8-11         uint32 format version (kAtlasFormatVersion; files of version 1 still load)
///   12-15        uint32 number of sections S (6, or 7 with the run state)
///   16-          S entries of the section table: char[16] name (NUL-padded), uint64 offset,
///                uint64 length, uint32 CRC-32 of the section's bytes
///   then         uint32 CRC-32 of the header (bytes 0 up to here)
///   then         the sections, in table order, back to back:
///     build      vocabulary checksum and words, settings hash and summary, built_with
///     imu        the run's inertial state (AtlasImuState)
///     maps       the active map id, then per map: id, created-keyframe flag
///     keyframes  per keyframe: map, id, time, camera, T_b_c, keypoints, descriptors, scale factors,
///                depths, segmentation layout, static threshold, Gamma, T_w_b, v_w_b, bias, the
///                IMU preintegration from the previous keyframe (its raw steps)
///     points     per map point: map, id, p_w, reference keyframe, descriptor, normal, distances,
///                visible/found counts, beta, observations (keyframe -> keypoint)
///     graph      per keyframe: previous/next, parent, children, covisibility, loop edges; per map:
///                origin keyframes, MapOrigin, reference map points
///     run        optional (version 2): the state of the run that saved the file at its last frame,
///                for a run resumed from it (run_state_io.h; the stages' parts in system/run_state.h)
/// Floats are stored as their IEEE bits, so a loaded atlas equals the saved one bit for bit. Every
/// count is checked against the bytes left before anything is allocated; every referenced id must
/// exist in the file. Derived per-image data (back-projected points, the keypoint grid, keypoint
/// clusters, static area ratio) is recomputed on load by the code paths that built it; the BoW
/// vectors and the keyframe database are rebuilt from the vocabulary.
///
/// Links to objects that are not saved (a covisibility edge or loop edge left pointing at a
/// keyframe culled meanwhile, which the live system skips) are not written.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "ltlo/core/calib.h"
#include "ltlo/core/eigen_types.h"
#include "ltlo/core/errors.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/ids.h"
#include "ltlo/map/run_state_io.h"

namespace bow {
class Vocabulary;
}

namespace ltlo::map {

inline constexpr std::uint32_t kAtlasFormatVersion = 2;
inline constexpr char kAtlasMagic[9] = "LTLOATL1";

/// What the atlas was built with; a file built with another vocabulary or other map-relevant
/// settings is refused by loadAtlas.
struct AtlasBuildInfo {
  std::uint64_t vocabulary_checksum = 0;  ///< bow::Vocabulary::checksum()
  std::uint32_t vocabulary_words = 0;     ///< bow::Vocabulary::numWords()
  std::uint64_t settings_hash = 0;        ///< FNV-1a 64 of settings_summary
  /// Human-readable map-relevant settings, one "key value" per line (mapSettingsSummary).
  std::string settings_summary;
  std::string built_with;  ///< free text, e.g. "rgbd_inertial <version>"
};

/// The map-relevant settings as text, one line each: camera model and intrinsics and image size,
/// lens coefficients, T_b_c, ORB levels and scale factor (doubles with 17 digits: a change of
/// any bit shows). A mismatch message shows the lines that differ.
std::string mapSettingsSummary(const SensorCalib& calib, int orb_levels, double orb_scale_factor);
/// Build info for `vocabulary` and `settings_summary` (hash filled in).
AtlasBuildInfo makeAtlasBuildInfo(const bow::Vocabulary& vocabulary, const std::string& settings_summary,
                                  const std::string& built_with);

/// The run's inertial state at save time (one for the whole atlas).
struct AtlasImuState {
  bool initialised = false;
  imu::ImuBias bias;
  Vec3 g_w = Vec3(0.0, 0.0, -9.81);
  Mat3 acceleration_covariance_w = Mat3::Zero();
  double time_offset_s = 0.0;  ///< IMU.TimeOffset + the online estimate (s)
};

/// What readAtlasSummary finds in a file (and loadAtlas returns alongside the atlas).
struct AtlasFileSummary {
  std::uint32_t format_version = 0;
  AtlasBuildInfo build;
  AtlasImuState imu;
  MapId active_map;
  struct MapSummary {
    MapId id;
    std::size_t keyframes = 0, map_points = 0;
    std::size_t loop_edges = 0;  ///< keyframe pairs linked by a loop edge
    /// Bounding box (m, world) of the keyframe camera centres and the map points (zero if empty).
    Vec3 extent_min = Vec3::Zero(), extent_max = Vec3::Zero();
    double t_first_s = 0.0, t_last_s = 0.0;  ///< first and last keyframe time (0 if none)
  };
  std::vector<MapSummary> maps;
  /// The run state (a version-2 file saved by a run): where it resumes and what it holds.
  struct RunSummary {
    std::uint64_t next_frame_index = 0;
    double last_frame_t_s = 0.0;
    std::size_t merged_maps = 0, culled_keyframes = 0, database_keyframes = 0;
    std::uint64_t stage_bytes = 0;  ///< the stages' parts (tracking, mapping, loop closing, records)
  };
  std::optional<RunSummary> run;
  std::uint64_t file_bytes = 0;
  struct Section {
    std::string name;
    std::uint64_t offset = 0, bytes = 0;
  };
  /// "header" (magic, version, table, header CRC) first, then the file's sections in file order;
  /// together they cover the file without gaps.
  std::vector<Section> sections;
};

/// A malformed or refused atlas file. what() reads
///   "<file>: section <name> at byte <offset>: <what> (<value>)"
/// (the value part is left out when empty); the offset is absolute in the file.
class AtlasFileError : public InputError {
 public:
  AtlasFileError(const std::string& file, const std::string& section, std::uint64_t offset, const std::string& what,
                 const std::string& value = "");
  const std::string& file() const { return file_; }
  const std::string& section() const { return section_; }
  std::uint64_t offset() const { return offset_; }

 private:
  std::string file_;
  std::string section_;
  std::uint64_t offset_;
};

/// Writes every map of `atlas` that is not merged away (with the active one) to `path`: to
/// path + ".part" first, then renamed over `path`, so a reader sees the old file or the new one,
/// whole. `run_state`, when given, is the run section's bytes (writeAtlasRunState, then the
/// stages' parts). Throws InputError naming the path when it cannot be written. Call with the
/// threads that change the atlas stopped or paused (it takes the maps' locks one object at a time).
void saveAtlas(Atlas& atlas, const AtlasImuState& imu, const AtlasBuildInfo& build, const std::string& path,
               const std::string* run_state = nullptr);

/// The run state of a loaded file, its atlas part applied (loadAtlas with restore_run_state).
struct LoadedRunState {
  RunStateHeader header;
  RunKeyFrames keyframes;  ///< the keyframes the stages' parts may name
  std::string file;
  std::string stage_bytes;        ///< the stages' parts, after the atlas part
  std::uint64_t stage_offset = 0;  ///< their byte offset in the file
  /// A reader over the stages' parts (valid while this object lives).
  ByteReader stages() const { return ByteReader(stage_bytes.data(), stage_bytes.size(), file, "run", stage_offset); }
};

struct LoadedAtlas {
  std::unique_ptr<Atlas> atlas;
  AtlasImuState imu;
  AtlasBuildInfo build;
  AtlasFileSummary summary;
  std::optional<LoadedRunState> run;
};

/// Reads and validates `path` and rebuilds the atlas: maps with their ids, the active map, every
/// keyframe (its BoW recomputed from its static keypoints with `vocabulary`, as local mapping
/// does, and added to the keyframe database), map point and link; the id source continues above
/// every id in the file. Throws AtlasFileError on a malformed file, or when it was built with
/// another vocabulary than `vocabulary` ("built with vocabulary checksum X (N words), this run
/// uses Y (M words)") or other settings than expected.settings_summary (the differing lines of
/// both); an empty expected.settings_summary skips the settings check (tools).
/// With `restore_run_state` the file must have a run section (else AtlasFileError naming it): its
/// atlas part is read and applied (id counters, map versions, merged maps, the database's order,
/// flags, culled keyframes) and LoadedAtlas::run returned; without, the section is only checked by
/// its CRC and the atlas is loaded as from a version-1 file.
LoadedAtlas loadAtlas(const std::string& path, const AtlasBuildInfo& expected, const bow::Vocabulary& vocabulary,
                      bool restore_run_state = false);
/// The same from bytes in memory; `name` stands for the file in messages (fuzzing, tests).
LoadedAtlas loadAtlasFromBytes(const std::string& bytes, const std::string& name, const AtlasBuildInfo& expected,
                               const bow::Vocabulary& vocabulary, bool restore_run_state = false);

/// Header and sections validated (CRCs, every record parsed), the counts and extents; needs no
/// vocabulary. Throws AtlasFileError as loadAtlas.
AtlasFileSummary readAtlasSummary(const std::string& path);
/// The same from bytes in memory; `name` stands for the file in messages.
AtlasFileSummary readAtlasSummaryFromBytes(const std::string& bytes, const std::string& name);

/// The map points of a file with beta >= min_beta (world frames of their maps), for a static-map
/// export; validated as readAtlasSummary.
struct AtlasPoint {
  MapId map;
  Vec3 p_w = Vec3::Zero();
  double beta = 1.0;
};
std::vector<AtlasPoint> readAtlasPoints(const std::string& path, double min_beta);

}  // namespace ltlo::map
