// libFuzzer target: the atlas file reader (ltlo/map/atlas_file.h) on arbitrary bytes: the summary
// reader (every section parsed, no vocabulary) and the loader (vocabulary check, BoW rebuild,
// keyframe database). Bad files must give AtlasFileError; an atlas that loads must be usable: its
// maps are walked and every keyframe's covisibles and points are looked up.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_atlas_vocabulary.h"
#include "fuzz_common.h"
#include "ltlo/map/atlas_file.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  ltlo::fuzz::quietLogging();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bow::Vocabulary vocabulary = ltlo::fuzz::atlasFuzzVocabulary();
  const std::string bytes = ltlo::fuzz::asText(data, size);
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
  return 0;
}
