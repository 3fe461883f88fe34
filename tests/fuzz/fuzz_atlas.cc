// libFuzzer target: the atlas file reader (ltlo/map/atlas_file.h) on arbitrary bytes: the summary
// reader (every section parsed, no vocabulary) and the loader (vocabulary check, BoW rebuild,
// keyframe database). Each input is read twice: as given, and with the header's and sections'
// CRCs recomputed, since a mutation almost never keeps a CRC right and the section readers behind
// the CRC check are what needs the fuzzing. Bad files must give AtlasFileError; an atlas that
// loads must be usable: its maps are walked and every keyframe's covisibles and points looked up.
#include <cstddef>
#include <cstdint>
#include <string>

#include "ltlo/map/binary_io.h"
#include "fuzz_atlas_vocabulary.h"
#include "fuzz_common.h"
#include "ltlo/map/atlas_file.h"

namespace {

constexpr std::size_t kSections = 6;
constexpr std::size_t kTableEntryBytes = 36;
constexpr std::size_t kHeaderCrcAt = 16 + kSections * kTableEntryBytes;

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
  if (bytes.size() < kHeaderCrcAt + 4) return bytes;
  for (std::size_t k = 0; k < kSections; ++k) {
    const std::size_t entry = 16 + k * kTableEntryBytes;
    const std::uint64_t offset = readU64(bytes, entry + 16), length = readU64(bytes, entry + 24);
    if (offset > bytes.size() || length > bytes.size() - offset) continue;
    putU32(bytes, entry + 32, ltlo::map::crc32(bytes.data() + offset, static_cast<std::size_t>(length)));
  }
  putU32(bytes, kHeaderCrcAt, ltlo::map::crc32(bytes.data(), kHeaderCrcAt));
  return bytes;
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
