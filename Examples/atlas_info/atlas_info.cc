// atlas_info: what an atlas file holds -- format version, what it was built with, the IMU state,
// per map keyframes, points, loop edges, extent and time span, the sections with their sizes.
//
//   atlas_info FILE [--ply OUT.ply] [--min-beta B]
//
// Prints `name value` lines. --ply writes the static map points (beta >= --min-beta, 0.5 as the
// run's static_map.ply) of every map in the file, in the static_map.ply layout. The file is
// validated as a load would (CRCs, every record, every id), without a vocabulary. Exit 0, 2 with
// the reader's message (file, section, byte offset) on a bad file.
#include <CLI/CLI.hpp>
#include <cinttypes>
#include <cstdio>
#include <string>
#include <vector>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/map/atlas_file.h"
#include "ltlo/system/run_outputs.h"

namespace {

using namespace ltlo;

void printVec3(const char* name, const Vec3& v) { std::printf("%s %.4f %.4f %.4f\n", name, v.x(), v.y(), v.z()); }

void printSummary(const map::AtlasFileSummary& summary) {
  std::printf("format_version %" PRIu32 "\n", summary.format_version);
  std::printf("file_bytes %" PRIu64 "\n", summary.file_bytes);
  std::printf("built_with %s\n", summary.build.built_with.c_str());
  std::printf("vocabulary_checksum 0x%016" PRIx64 "\n", summary.build.vocabulary_checksum);
  std::printf("vocabulary_words %" PRIu32 "\n", summary.build.vocabulary_words);
  std::printf("settings_hash 0x%016" PRIx64 "\n", summary.build.settings_hash);
  std::size_t start = 0;
  const std::string& settings = summary.build.settings_summary;
  while (start < settings.size()) {  // one line per setting, as the file holds them
    const std::size_t end = settings.find('\n', start);
    std::printf("settings %s\n", settings.substr(start, end - start).c_str());
    start = end == std::string::npos ? settings.size() : end + 1;
  }
  std::printf("imu_initialised %d\n", summary.imu.initialised ? 1 : 0);
  printVec3("imu_gravity_w", summary.imu.g_w);
  printVec3("imu_gyro_bias", summary.imu.bias.b_g);
  printVec3("imu_acc_bias", summary.imu.bias.b_a);
  std::printf("imu_time_offset_s %.6f\n", summary.imu.time_offset_s);
  std::printf("active_map %" PRIu64 "\n", summary.active_map.value);
  std::printf("maps %zu\n", summary.maps.size());
  for (const map::AtlasFileSummary::MapSummary& m : summary.maps) {
    std::printf("map %" PRIu64 " keyframes %zu map_points %zu loop_edges %zu t_first_s %.6f t_last_s %.6f\n",
                m.id.value, m.keyframes, m.map_points, m.loop_edges, m.t_first_s, m.t_last_s);
    std::printf("map %" PRIu64 " extent_min %.4f %.4f %.4f extent_max %.4f %.4f %.4f\n", m.id.value, m.extent_min.x(),
                m.extent_min.y(), m.extent_min.z(), m.extent_max.x(), m.extent_max.y(), m.extent_max.z());
  }
  if (summary.run) {
    // A run's state to resume (format 2): the frame it goes on at and the atlas part's contents.
    std::printf("run_next_frame %" PRIu64 "\n", summary.run->next_frame_index);
    std::printf("run_last_frame_t_s %.6f\n", summary.run->last_frame_t_s);
    std::printf("run_merged_maps %zu\nrun_culled_keyframes %zu\nrun_database_keyframes %zu\n", summary.run->merged_maps,
                summary.run->culled_keyframes, summary.run->database_keyframes);
    std::printf("run_stage_bytes %" PRIu64 "\n", summary.run->stage_bytes);
  }
  for (const map::AtlasFileSummary::Section& section : summary.sections) {
    std::printf("section %s offset %" PRIu64 " bytes %" PRIu64 "\n", section.name.c_str(), section.offset,
                section.bytes);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"What an atlas file holds: maps, keyframes, points, extent, format, what it was built with"};
  std::string atlas_path, ply_path;
  double min_beta = 0.5;
  app.add_option("file", atlas_path, "atlas file (rgbd_inertial --save-atlas)")->required();
  app.add_option("--ply", ply_path, "write the static map points of the file to this PLY");
  app.add_option("--min-beta", min_beta, "static score a point needs for --ply")->check(CLI::Range(0.0, 1.0));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  log::initFromEnvironment();
  try {
    printSummary(map::readAtlasSummary(atlas_path));
    if (!ply_path.empty()) {
      std::vector<system::MapPointRecord> records;
      for (const map::AtlasPoint& point : map::readAtlasPoints(atlas_path, min_beta)) {
        system::MapPointRecord record;
        record.p_w = point.p_w;
        record.beta = point.beta;
        records.push_back(record);
      }
      const int written = system::writeStaticMapPly(ply_path, records, min_beta);
      std::printf("ply_points %d\n", written);
    }
  } catch (const InputError& e) {
    std::fprintf(stderr, "atlas_info: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "atlas_info: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
