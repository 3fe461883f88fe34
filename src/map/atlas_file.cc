// The atlas file (atlas_file.h): header and section table, the build and imu sections, atomic
// save, load, and the summary.
#include "ltlo/map/atlas_file.h"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>

#include "atlas_file_access.h"
#include "atlas_file_sections.h"
#include "bow/vocabulary.h"
#include "ltlo/core/camera_model.h"

namespace ltlo::map {

namespace {

constexpr std::size_t kNameBytes = 16;
constexpr std::size_t kTableEntryBytes = kNameBytes + 8 + 8 + 4;
constexpr std::size_t kFixedHeaderBytes = 8 + 4 + 4;
/// The sections of a file, in file order: version 1 has the first six, version 2 the six or all
/// seven (the run state is optional).
const std::vector<std::string>& sectionNames() {
  static const std::vector<std::string> names = {"build", "imu", "maps", "keyframes", "points", "graph", "run"};
  return names;
}
constexpr std::size_t kMapSections = 6;
constexpr std::size_t kRunSection = 6;

std::string hex64(std::uint64_t v) {
  char text[24];
  std::snprintf(text, sizeof(text), "0x%016" PRIx64, v);
  return text;
}

std::string hex32(std::uint32_t v) {
  char text[16];
  std::snprintf(text, sizeof(text), "0x%08" PRIx32, v);
  return text;
}

// ---- build and imu sections ----

void writeBuildSection(const AtlasBuildInfo& build, ByteWriter& out) {
  out.u64(build.vocabulary_checksum);
  out.u32(build.vocabulary_words);
  out.u64(build.settings_hash);
  out.text(build.settings_summary);
  out.text(build.built_with);
}

AtlasBuildInfo readBuildSection(ByteReader& in) {
  AtlasBuildInfo build;
  build.vocabulary_checksum = in.u64("vocabulary checksum");
  build.vocabulary_words = in.u32("vocabulary words");
  const std::uint64_t hash_offset = in.fileOffset();
  build.settings_hash = in.u64("settings hash");
  build.settings_summary = in.text("settings summary");
  build.built_with = in.text("built with");
  if (build.settings_hash != fnv1a64(build.settings_summary)) {
    in.failAt(hash_offset, "settings hash does not match the settings summary", hex64(build.settings_hash));
  }
  in.expectEnd();
  return build;
}

void writeImuSection(const AtlasImuState& imu, ByteWriter& out) {
  out.boolean(imu.initialised);
  out.vec3(imu.bias.b_g);
  out.vec3(imu.bias.b_a);
  out.vec3(imu.g_w);
  out.mat3(imu.acceleration_covariance_w);
  out.f64(imu.time_offset_s);
}

AtlasImuState readImuSection(ByteReader& in) {
  AtlasImuState imu;
  imu.initialised = in.boolean("imu initialised");
  imu.bias.b_g = in.vec3("gyro bias");
  imu.bias.b_a = in.vec3("accelerometer bias");
  imu.g_w = in.vec3("gravity");
  imu.acceleration_covariance_w = in.mat3("acceleration covariance");
  imu.time_offset_s = in.finiteF64("time offset");
  in.expectEnd();
  return imu;
}

// ---- header ----

struct SectionEntry {
  std::string name;
  std::uint64_t offset = 0, bytes = 0;
  std::uint32_t crc = 0;
};

std::string fileHeader(const std::vector<SectionEntry>& sections) {
  ByteWriter out;
  out.raw(kAtlasMagic, 8);
  out.u32(kAtlasFormatVersion);
  out.u32(static_cast<std::uint32_t>(sections.size()));
  for (const SectionEntry& section : sections) {
    char name[kNameBytes] = {};
    std::copy_n(section.name.begin(), std::min(section.name.size(), kNameBytes - 1), name);
    out.raw(name, kNameBytes);
    out.u64(section.offset);
    out.u64(section.bytes);
    out.u32(section.crc);
  }
  out.u32(crc32(out.bytes().data(), out.size()));
  return out.bytes();
}

std::string printable(const std::string& bytes) {
  std::string text;
  for (const char c : bytes) text += (c >= 32 && c < 127) ? c : '?';
  return text;
}

SectionEntry readTableEntry(ByteReader& in, const std::string& expected_name, std::uint32_t version) {
  const std::uint64_t offset = in.fileOffset();
  char name[kNameBytes];
  in.raw(name, kNameBytes, "section name");
  SectionEntry entry;
  entry.name.assign(name, strnlen(name, kNameBytes));
  if (entry.name != expected_name) {
    in.failAt(offset,
              "section table names '" + printable(entry.name) + "' where version " + std::to_string(version) +
                  " has '" + expected_name + "'",
              printable(entry.name));
  }
  entry.offset = in.u64("section offset");
  entry.bytes = in.u64("section length");
  entry.crc = in.u32("section CRC");
  return entry;
}

/// Magic, version, section table and header CRC; each section's place within the file and its CRC.
std::vector<SectionEntry> readHeader(const std::string& bytes, const std::string& name) {
  ByteReader in(bytes.data(), bytes.size(), name, "header", 0);
  char magic[8];
  in.raw(magic, 8, "magic");
  if (std::string(magic, 8) != std::string(kAtlasMagic, 8)) {
    in.failAt(0, "not an atlas file (magic is not " + std::string(kAtlasMagic) + ")", printable(std::string(magic, 8)));
  }
  const std::uint32_t version = in.u32("format version");
  if (version < 1 || version > kAtlasFormatVersion) {
    in.failAt(8, "unsupported format version, this build reads versions 1 to " + std::to_string(kAtlasFormatVersion),
              std::to_string(version));
  }
  const std::uint32_t count = in.u32("section count");
  if (version == 1 && count != kMapSections) {
    in.failAt(12, "version 1 has " + std::to_string(kMapSections) + " sections", std::to_string(count));
  }
  if (version == 2 && count != kMapSections && count != kMapSections + 1) {
    in.failAt(12, "version 2 has " + std::to_string(kMapSections) + " or " + std::to_string(kMapSections + 1) +
                      " sections", std::to_string(count));
  }
  std::vector<SectionEntry> sections;
  for (std::uint32_t k = 0; k < count; ++k) sections.push_back(readTableEntry(in, sectionNames()[k], version));
  const std::uint64_t crc_offset = in.fileOffset();
  const std::uint32_t header_crc = in.u32("header CRC");
  const std::uint32_t computed = crc32(bytes.data(), static_cast<std::size_t>(crc_offset));
  if (header_crc != computed)
    in.failAt(crc_offset, "header CRC mismatch, computed " + hex32(computed), hex32(header_crc));
  std::uint64_t expected_offset = in.fileOffset();
  for (const SectionEntry& section : sections) {
    ByteReader at(bytes.data(), 0, name, section.name, section.offset);
    if (section.offset != expected_offset)
      at.fail("section does not follow the previous one at byte " + std::to_string(expected_offset),
              std::to_string(section.offset));
    if (section.bytes > bytes.size() - section.offset) {
      at.fail("truncated: the section's " + std::to_string(section.bytes) + " bytes end past the file's " +
                  std::to_string(bytes.size()),
              std::to_string(bytes.size() - section.offset) + " bytes left");
    }
    const std::uint32_t crc = crc32(bytes.data() + section.offset, static_cast<std::size_t>(section.bytes));
    if (crc != section.crc) at.fail("CRC mismatch, computed " + hex32(crc), hex32(section.crc));
    expected_offset = section.offset + section.bytes;
  }
  if (expected_offset != bytes.size()) {
    ByteReader(bytes.data(), 0, name, sections.back().name, expected_offset)
        .fail("bytes after the last section", std::to_string(bytes.size() - expected_offset));
  }
  return sections;
}

ByteReader sectionReader(const std::string& bytes, const std::string& name, const SectionEntry& section) {
  return ByteReader(bytes.data() + section.offset, static_cast<std::size_t>(section.bytes), name, section.name,
                    section.offset);
}

std::string readWholeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw AtlasFileError(path, "header", 0, "cannot open the atlas file");
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw AtlasFileError(path, "header", 0, "cannot read the atlas file");
  return bytes;
}

// ---- checks against this run ----

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

void checkBuild(const AtlasBuildInfo& file, const AtlasBuildInfo& expected, const bow::Vocabulary& vocabulary,
                const std::string& name, const SectionEntry& build_section) {
  const std::uint64_t checksum = vocabulary.checksum();
  if (file.vocabulary_checksum != checksum || file.vocabulary_words != vocabulary.numWords()) {
    throw AtlasFileError(name, "build", build_section.offset,
                         "built with vocabulary checksum " + hex64(file.vocabulary_checksum) + " (" +
                             std::to_string(file.vocabulary_words) + " words), this run uses " + hex64(checksum) +
                             " (" + std::to_string(vocabulary.numWords()) + " words)");
  }
  if (expected.settings_summary.empty() || fnv1a64(expected.settings_summary) == file.settings_hash) return;
  const std::vector<std::string> file_lines = lines(file.settings_summary);
  const std::vector<std::string> run_lines = lines(expected.settings_summary);
  std::string file_only, run_only;
  for (const std::string& line : file_lines) {
    if (std::find(run_lines.begin(), run_lines.end(), line) == run_lines.end())
      file_only += (file_only.empty() ? "" : "; ") + line;
  }
  for (const std::string& line : run_lines) {
    if (std::find(file_lines.begin(), file_lines.end(), line) == file_lines.end())
      run_only += (run_only.empty() ? "" : "; ") + line;
  }
  throw AtlasFileError(
      name, "build", build_section.offset + 20,
      "built with other map settings: the file has \"" + file_only + "\", this run has \"" + run_only + "\"");
}

// ---- reading the atlas ----

struct ParsedFile {
  AtlasRestore restore;
  AtlasBuildInfo build;
  AtlasImuState imu;
  std::vector<SectionEntry> sections;
  bool has_run_state() const { return sections.size() > kRunSection; }
};

/// Header, CRCs and build first (so a refused vocabulary costs no parsing), then every section.
ParsedFile parseAtlas(const std::string& bytes, const std::string& name, std::size_t num_words,
                      const AtlasBuildInfo* expected, const bow::Vocabulary* vocabulary) {
  ParsedFile parsed;
  parsed.sections = readHeader(bytes, name);
  const auto section = [&](int k) { return sectionReader(bytes, name, parsed.sections[static_cast<std::size_t>(k)]); };
  ByteReader build = section(0);
  parsed.build = readBuildSection(build);
  if (vocabulary != nullptr) checkBuild(parsed.build, *expected, *vocabulary, name, parsed.sections[0]);
  ByteReader imu = section(1);
  parsed.imu = readImuSection(imu);
  parsed.restore.atlas = AtlasFileAccess::emptyAtlas(num_words);
  ByteReader maps = section(2);
  readMapsSection(maps, parsed.restore);
  ByteReader keyframes = section(3);
  readKeyFramesSection(keyframes, parsed.restore);
  ByteReader points = section(4);
  readPointsSection(points, parsed.restore);
  ByteReader graph = section(5);
  readGraphSection(graph, parsed.restore);
  return parsed;
}

/// The run section's atlas part read against the parsed atlas (not applied); `stages` is left at
/// the stages' parts.
AtlasRunState readRunSection(const std::string& bytes, const std::string& name, ParsedFile& parsed,
                             ByteReader* stages) {
  *stages = sectionReader(bytes, name, parsed.sections[kRunSection]);
  return readAtlasRunState(*stages, *parsed.restore.atlas);
}

AtlasFileSummary::MapSummary summariseMap(const Map& map) {
  AtlasFileSummary::MapSummary summary;
  summary.id = map.id();
  bool first = true;
  auto extend = [&](const Vec3& p) {
    summary.extent_min = first ? p : summary.extent_min.cwiseMin(p);
    summary.extent_max = first ? p : summary.extent_max.cwiseMax(p);
    first = false;
  };
  std::set<std::pair<KeyFrameId, KeyFrameId>> loop_pairs;
  const std::vector<std::shared_ptr<KeyFrame>> keyframes = map.keyFrames();
  for (const std::shared_ptr<KeyFrame>& kf : keyframes) {
    extend(kf->cameraCentre_w());
    summary.t_first_s = summary.keyframes == 0 ? kf->t_s() : std::min(summary.t_first_s, kf->t_s());
    summary.t_last_s = summary.keyframes == 0 ? kf->t_s() : std::max(summary.t_last_s, kf->t_s());
    ++summary.keyframes;
    for (const KeyFrameId other : kf->loopEdges())
      loop_pairs.emplace(std::min(kf->id(), other), std::max(kf->id(), other));
  }
  for (const std::shared_ptr<MapPoint>& point : map.mapPoints()) {
    extend(point->p_w());
    ++summary.map_points;
  }
  summary.loop_edges = loop_pairs.size();
  return summary;
}

AtlasFileSummary summarise(const ParsedFile& parsed, std::uint64_t file_bytes, std::uint32_t format_version) {
  AtlasFileSummary summary;
  summary.format_version = format_version;
  summary.build = parsed.build;
  summary.imu = parsed.imu;
  summary.active_map = parsed.restore.active;
  for (const auto& [id, map] : parsed.restore.maps) summary.maps.push_back(summariseMap(*map));
  summary.file_bytes = file_bytes;
  summary.sections.push_back({"header", 0, parsed.sections.front().offset});
  for (const SectionEntry& section : parsed.sections)
    summary.sections.push_back({section.name, section.offset, section.bytes});
  return summary;
}

/// The format version of a file whose header was read (readHeader checked it).
std::uint32_t fileVersion(const std::string& bytes) {
  std::uint32_t version = 0;
  for (int k = 0; k < 4; ++k) version |= static_cast<std::uint32_t>(static_cast<std::uint8_t>(bytes[8 + k])) << (8 * k);
  return version;
}

AtlasFileSummary::RunSummary runSummary(const AtlasRunState& state, std::size_t stage_bytes) {
  AtlasFileSummary::RunSummary run;
  run.next_frame_index = state.header.next_frame_index;
  run.last_frame_t_s = state.header.last_frame_t_s;
  run.merged_maps = state.merged.size();
  run.culled_keyframes = state.culled.size();
  run.database_keyframes = state.database.size();
  run.stage_bytes = stage_bytes;
  return run;
}

}  // namespace

AtlasFileError::AtlasFileError(const std::string& file, const std::string& section, std::uint64_t offset,
                               const std::string& what, const std::string& value)
    : InputError(file + ": section " + section + " at byte " + std::to_string(offset) + ": " + what +
                 (value.empty() ? "" : " (" + value + ")")),
      file_(file),
      section_(section),
      offset_(offset) {}

std::string mapSettingsSummary(const SensorCalib& calib, int orb_levels, double orb_scale_factor) {
  const PinholeCamera& camera = calib.camera.camera;
  const LensDistortion& lens = calib.camera.lens;
  const Quat& q = calib.imu.T_b_c.quaternion();
  const Vec3& t = calib.imu.T_b_c.translation();
  const auto exact = exactNumberText;  // every bit of each value shows
  std::ostringstream os;
  os << "camera fx=" << exact(camera.fx()) << " fy=" << exact(camera.fy()) << " cx=" << exact(camera.cx())
     << " cy=" << exact(camera.cy()) << " width=" << camera.width() << " height=" << camera.height() << "\n";
  os << "lens " << lensModelName(lens.model) << " k1=" << exact(lens.k1) << " k2=" << exact(lens.k2)
     << " k3=" << exact(lens.k3) << " k4=" << exact(lens.k4) << " k5=" << exact(lens.k5) << " k6=" << exact(lens.k6)
     << " p1=" << exact(lens.p1) << " p2=" << exact(lens.p2) << "\n";
  os << "T_b_c q=" << exact(q.x()) << "," << exact(q.y()) << "," << exact(q.z()) << "," << exact(q.w())
     << " t=" << exact(t.x()) << "," << exact(t.y()) << "," << exact(t.z()) << "\n";
  os << "orb levels=" << orb_levels << " scale_factor=" << exact(orb_scale_factor) << "\n";
  return os.str();
}

AtlasBuildInfo makeAtlasBuildInfo(const bow::Vocabulary& vocabulary, const std::string& settings_summary,
                                  const std::string& built_with) {
  AtlasBuildInfo build;
  build.vocabulary_checksum = vocabulary.checksum();
  build.vocabulary_words = static_cast<std::uint32_t>(vocabulary.numWords());
  build.settings_summary = settings_summary;
  build.settings_hash = fnv1a64(settings_summary);
  build.built_with = built_with;
  return build;
}

void saveAtlas(Atlas& atlas, const AtlasImuState& imu, const AtlasBuildInfo& build, const std::string& path,
               const std::string* run_state) {
  const AtlasSnapshot snapshot = snapshotAtlas(atlas);
  AtlasBuildInfo stored = build;
  stored.settings_hash = fnv1a64(build.settings_summary);  // the file's hash always matches its text
  std::vector<ByteWriter> bodies(run_state != nullptr ? kMapSections + 1 : kMapSections);
  writeBuildSection(stored, bodies[0]);
  writeImuSection(imu, bodies[1]);
  writeMapsSection(snapshot, bodies[2]);
  writeKeyFramesSection(snapshot, bodies[3]);
  writePointsSection(snapshot, bodies[4]);
  writeGraphSection(snapshot, bodies[5]);
  if (run_state != nullptr) bodies[kRunSection].raw(run_state->data(), run_state->size());
  std::vector<SectionEntry> sections;
  std::uint64_t offset = kFixedHeaderBytes + bodies.size() * kTableEntryBytes + 4;
  for (std::size_t k = 0; k < bodies.size(); ++k) {
    const std::string& body = bodies[k].bytes();
    sections.push_back({sectionNames()[k], offset, body.size(), crc32(body.data(), body.size())});
    offset += body.size();
  }
  const std::string part_path = path + ".part";
  {
    std::ofstream out(part_path, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError(part_path, 0, "cannot open the atlas file for writing");
    const std::string header = fileHeader(sections);
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    for (const ByteWriter& body : bodies) out.write(body.bytes().data(), static_cast<std::streamsize>(body.size()));
    out.close();
    if (!out) {
      std::remove(part_path.c_str());
      throw InputError(part_path, 0, "writing the atlas file failed");
    }
  }
  std::error_code error;
  std::filesystem::rename(part_path, path, error);
  if (error) {
    std::remove(part_path.c_str());
    throw InputError(path, 0, "cannot replace the atlas file: " + error.message());
  }
}

LoadedAtlas loadAtlasFromBytes(const std::string& bytes, const std::string& name, const AtlasBuildInfo& expected,
                               const bow::Vocabulary& vocabulary, bool restore_run_state) {
  ParsedFile parsed = parseAtlas(bytes, name, vocabulary.numWords(), &expected, &vocabulary);
  if (restore_run_state && !parsed.has_run_state()) {
    const SectionEntry& last = parsed.sections.back();
    throw AtlasFileError(name, "run", last.offset + last.bytes,
                         "no run state to resume from (the file was saved without one, or by a build before format "
                         "version 2)");
  }
  Atlas& atlas = *parsed.restore.atlas;
  KeyFrameId max_keyframe;
  MapPointId max_point;
  MapId max_map;
  for (const auto& [id, map] : parsed.restore.maps) max_map = max_map.valid() ? std::max(max_map, id) : id;
  for (const auto& [id, kf] : parsed.restore.keyframes) {
    max_keyframe = max_keyframe.valid() ? std::max(max_keyframe, id) : id;
    // As local mapping computes it when Gamma changes.
    auto [bow_vector, feature_vector] = staticKeypointsBow(*kf, vocabulary);
    kf->setBow(std::move(bow_vector), std::move(feature_vector));
    atlas.keyFrameDatabase().add(kf);
  }
  for (const auto& [id, point] : parsed.restore.points) max_point = max_point.valid() ? std::max(max_point, id) : id;
  AtlasFileAccess::ids(atlas).reserveAbove(max_keyframe, max_point, max_map);
  LoadedAtlas loaded;
  loaded.summary = summarise(parsed, bytes.size(), fileVersion(bytes));
  if (restore_run_state) {
    ByteReader stages(bytes.data(), 0, name, "run", 0);
    AtlasRunState state = readRunSection(bytes, name, parsed, &stages);
    loaded.summary.run = runSummary(state, stages.remaining());
    LoadedRunState run;
    run.header = state.header;
    run.keyframes = applyAtlasRunState(std::move(state), atlas);
    run.file = name;
    run.stage_offset = stages.fileOffset();
    run.stage_bytes = bytes.substr(static_cast<std::size_t>(run.stage_offset), stages.remaining());
    loaded.run = std::move(run);
  }
  loaded.imu = parsed.imu;
  loaded.build = parsed.build;
  loaded.atlas = std::move(parsed.restore.atlas);
  return loaded;
}

LoadedAtlas loadAtlas(const std::string& path, const AtlasBuildInfo& expected, const bow::Vocabulary& vocabulary,
                      bool restore_run_state) {
  return loadAtlasFromBytes(readWholeFile(path), path, expected, vocabulary, restore_run_state);
}

AtlasFileSummary readAtlasSummaryFromBytes(const std::string& bytes, const std::string& name) {
  ParsedFile parsed = parseAtlas(bytes, name, 0, nullptr, nullptr);
  AtlasFileSummary summary = summarise(parsed, bytes.size(), fileVersion(bytes));
  if (parsed.has_run_state()) {
    ByteReader stages(bytes.data(), 0, name, "run", 0);
    const AtlasRunState state = readRunSection(bytes, name, parsed, &stages);
    summary.run = runSummary(state, stages.remaining());
  }
  return summary;
}

AtlasFileSummary readAtlasSummary(const std::string& path) {
  return readAtlasSummaryFromBytes(readWholeFile(path), path);
}

std::vector<AtlasPoint> readAtlasPoints(const std::string& path, double min_beta) {
  const std::string bytes = readWholeFile(path);
  const ParsedFile parsed = parseAtlas(bytes, path, 0, nullptr, nullptr);
  std::vector<AtlasPoint> points;
  for (const auto& [id, map] : parsed.restore.maps) {
    for (const std::shared_ptr<MapPoint>& point : map->mapPoints()) {
      const double beta = point->beta();
      if (beta >= min_beta) points.push_back({id, point->p_w(), beta});
    }
  }
  return points;
}

}  // namespace ltlo::map
