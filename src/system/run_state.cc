// The run section of an atlas file put together (ltlo/system/run_state.h).
#include "ltlo/system/run_state.h"

#include <sstream>

#include "ltlo/loop/loop_closer.h"
#include "ltlo/mapping/local_mapper.h"
#include "ltlo/system/run_recorder.h"
#include "ltlo/tracking/frame_builder.h"
#include "ltlo/tracking/frame_segmenter.h"
#include "ltlo/tracking/tracker.h"

namespace ltlo::system {

std::string writeRunState(map::Atlas& atlas, const map::RunStateHeader& header, std::uint64_t settings_fingerprint,
                          const RunStages& stages) {
  map::KeyFrameRefs refs;
  map::ByteWriter parts;
  parts.u64(settings_fingerprint);
  parts.u64(stages.imu_generation);
  parts.f64(stages.imu_shift.current_s());
  stages.tracker.writeState(parts, refs);
  parts.text(stages.segmenter != nullptr ? stages.segmenter->name() : "");
  if (stages.segmenter != nullptr) stages.segmenter->writeState(parts);
  stages.mapper.writeState(parts);
  stages.closer.writeState(parts);
  stages.recorder.writeState(parts, refs);
  // The atlas part last written, first in the file: it holds the culled keyframes named above.
  map::ByteWriter section;
  map::writeAtlasRunState(atlas, header, refs, section);
  section.raw(parts.bytes().data(), parts.size());
  return std::move(section.bytes());
}

std::uint64_t readRunState(const map::LoadedRunState& run, const RunStages& stages) {
  map::ByteReader in = run.stages();
  const std::uint64_t fingerprint = in.u64("settings fingerprint");
  stages.imu_generation = in.u64("IMU generation");
  stages.imu_shift.restore(in.finiteF64("IMU interval shift"));
  stages.tracker.readState(in, run.keyframes);
  const std::uint64_t segmenter_offset = in.fileOffset();
  const std::string segmenter = in.text("segmenter", 64);
  const std::string current = stages.segmenter != nullptr ? stages.segmenter->name() : "";
  if (segmenter != current) {
    in.failAt(segmenter_offset, "saved with the segmenter '" + segmenter + "', this run's is '" + current + "'",
              segmenter);
  }
  if (stages.segmenter != nullptr) stages.segmenter->readState(in);
  stages.mapper.readState(in);
  stages.closer.readState(in);
  stages.recorder.readState(in, run.keyframes);
  in.expectEnd();
  return fingerprint;
}

std::uint64_t runStateFingerprint(const std::string& settings_description, bool use_imu, bool oracle_masks) {
  std::istringstream lines(settings_description);
  std::string kept;
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("settings = ", 0) == 0 || line.rfind("calibration = ", 0) == 0 || line.rfind("--set ", 0) == 0)
      continue;
    kept += line + "\n";
  }
  kept += use_imu ? "imu\n" : "no imu\n";
  kept += oracle_masks ? "oracle masks\n" : "";
  return map::fnv1a64(kept);
}

}  // namespace ltlo::system
