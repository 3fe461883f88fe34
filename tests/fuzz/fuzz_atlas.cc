// libFuzzer target: the atlas file reader (ltlo/map/atlas_file.h) on arbitrary bytes: the summary
// reader (every section parsed, no vocabulary), the loader (vocabulary check, BoW rebuild,
// keyframe database) and, for a version-2 file with a run section, the resume: the atlas part of
// the run state applied and every stage's part read into a tracker, dense segmenter, local mapper,
// loop closer and run recorder (system/run_state.h). Each input is read twice: as given, and with
// the header's and sections' CRCs recomputed, since a mutation almost never keeps a CRC right and
// the section readers behind the CRC check are what needs the fuzzing. Bad files must give
// AtlasFileError; an atlas that loads must be usable: its maps are walked and every keyframe's
// covisibles and points looked up.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "fuzz_atlas_vocabulary.h"
#include "fuzz_common.h"
#include "ltlo/loop/loop_closer.h"
#include "ltlo/map/atlas_file.h"
#include "ltlo/map/binary_io.h"
#include "ltlo/mapping/local_mapper.h"
#include "ltlo/system/run_recorder.h"
#include "ltlo/system/run_state.h"
#include "ltlo/tracking/dense_segmenter.h"
#include "ltlo/tracking/frame_builder.h"
#include "ltlo/tracking/tracker.h"

namespace {

constexpr std::size_t kTableEntryBytes = 36;

/// Sections in the file's table (6, or 7 with the run state); 0 when the header is too short.
std::size_t sectionCount(const std::string& bytes) {
  if (bytes.size() < 16) return 0;
  const std::size_t count = static_cast<std::uint8_t>(bytes[12]);
  return count == 6 || count == 7 ? count : 0;
}

std::uint64_t readU64(const std::string& bytes, std::size_t at) {
  std::uint64_t v = 0;
  for (int k = 0; k < 8; ++k) v |= static_cast<std::uint64_t>(static_cast<std::uint8_t>(bytes[at + k])) << (8 * k);
  return v;
}

void putU32(std::string& bytes, std::size_t at, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) bytes[at + k] = static_cast<char>((v >> (8 * k)) & 0xFF);
}

/// The input with every section CRC that lies within the file, and the header CRC, made right.
std::string withFixedCrcs(std::string bytes) {
  const std::size_t sections = sectionCount(bytes);
  const std::size_t header_crc_at = 16 + sections * kTableEntryBytes;
  if (sections == 0 || bytes.size() < header_crc_at + 4) return bytes;
  for (std::size_t k = 0; k < sections; ++k) {
    const std::size_t entry = 16 + k * kTableEntryBytes;
    const std::uint64_t offset = readU64(bytes, entry + 16), length = readU64(bytes, entry + 24);
    if (offset > bytes.size() || length > bytes.size() - offset) continue;
    putU32(bytes, entry + 32, ltlo::map::crc32(bytes.data() + offset, static_cast<std::size_t>(length)));
  }
  putU32(bytes, header_crc_at, ltlo::map::crc32(bytes.data(), header_crc_at));
  return bytes;
}

/// The stages of a run, with default options, whose state a resumed run reads from the file.
struct FuzzStages {
  explicit FuzzStages(ltlo::map::Atlas& atlas, const bow::Vocabulary& vocabulary)
      : tracker(atlas, ltlo::tracking::TrackerOptions(), levelSigma2()),
        mapper(atlas, ltlo::mapping::LocalMapperOptions(), levelSigma2()),
        closer(atlas, ltlo::loop::LoopCloserOptions(), ltlo::loop::MappingControl()),
        recorder(atlas, ltlo::TrackingOptions()) {
    tracker.setVocabulary(&vocabulary);
    tracker.setSegmenter(std::make_unique<ltlo::tracking::DenseSegmenter>(
        ltlo::SegmentationOptions(), ltlo::DenseOptions(), ltlo::LocalMappingOptions(),
        ltlo::PinholeCamera(250.0, 250.0, 159.5, 119.5, 320, 240)));
  }
  static std::vector<float> levelSigma2() { return {1.0f, 1.44f, 2.07f, 2.99f, 4.3f, 6.19f, 8.92f, 12.84f}; }
  ltlo::system::RunStages view() {
    return {tracker, tracker.segmenter(), mapper, closer, recorder, imu_shift, imu_generation};
  }
  ltlo::tracking::Tracker tracker;
  ltlo::mapping::LocalMapper mapper;
  ltlo::loop::LoopCloser closer;
  ltlo::system::RunRecorder recorder;
  ltlo::tracking::ImuShiftRamp imu_shift;
  std::uint64_t imu_generation = 0;
};

void resumeFrom(const std::string& bytes, const bow::Vocabulary& vocabulary) {
  if (sectionCount(bytes) != 7) return;
  try {
    ltlo::map::LoadedAtlas loaded = ltlo::map::loadAtlasFromBytes(bytes, "fuzz.atlas", {}, vocabulary, true);
    FuzzStages stages(*loaded.atlas, vocabulary);
    (void)ltlo::system::readRunState(*loaded.run, stages.view());
    (void)stages.recorder.trajectory(ltlo::system::CarriedCorrection::kBridge);
  } catch (const ltlo::map::AtlasFileError&) {
  }
}

void readBothWays(const std::string& bytes, const bow::Vocabulary& vocabulary) {
  try {
    (void)ltlo::map::readAtlasSummaryFromBytes(bytes, "fuzz.atlas");
  } catch (const ltlo::map::AtlasFileError&) {
  }
  try {
    ltlo::map::LoadedAtlas loaded = ltlo::map::loadAtlasFromBytes(bytes, "fuzz.atlas", {}, vocabulary);
    for (const ltlo::map::MapId id : loaded.atlas->mapIds()) {
      ltlo::map::Map& map = *loaded.atlas->map(id);
      for (const auto& kf : map.keyFrames()) {
        for (const auto& [other, weight] : kf->covisibles()) (void)map.keyFrame(other);
        for (const ltlo::map::MapPointId point : kf->mapPoints()) (void)map.mapPoint(point);
        (void)kf->staticAreaRatio();
      }
    }
  } catch (const ltlo::map::AtlasFileError&) {
  }
  resumeFrom(bytes, vocabulary);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  ltlo::fuzz::quietLogging();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bow::Vocabulary vocabulary = ltlo::fuzz::atlasFuzzVocabulary();
  const std::string bytes = ltlo::fuzz::asText(data, size);
  readBothWays(bytes, vocabulary);
  readBothWays(withFixedCrcs(bytes), vocabulary);
  return 0;
}
