#pragma once
/// The run state of an atlas file put together (issue 31): the run section (map/run_state_io.h)
/// holds the atlas's part first, then the stages' parts in this order:
///   system     fingerprint of the settings the run used, the IMU generation tracking took last,
///              the IMU interval ramp (tracking::ImuShiftRamp)
///   tracker    Tracker::writeState
///   segmenter  its name, then FrameSegmenter::writeState
///   mapping    LocalMapper::writeState
///   loop       LoopCloser::writeState
///   records    RunRecorder::writeState
/// Written after System::shutdown() (single-threaded: the state after the last frame, as the next
/// frame would find it; threaded: after local mapping and loop closing drained their queues and
/// the full BA finished, so a resumed run goes on from the drained state).
#include <cstdint>
#include <optional>
#include <string>

#include "ltlo/map/atlas.h"
#include "ltlo/map/atlas_file.h"
#include "ltlo/map/run_state_io.h"

namespace ltlo::tracking {
class FrameSegmenter;
class ImuShiftRamp;
class Tracker;
}  // namespace ltlo::tracking
namespace ltlo::mapping {
class LocalMapper;
}
namespace ltlo::loop {
class LoopCloser;
}

namespace ltlo::system {

class RunRecorder;

/// The stages whose state the run section holds, and System's own.
struct RunStages {
  tracking::Tracker& tracker;
  tracking::FrameSegmenter* segmenter;  ///< may be absent (a tracker without one)
  mapping::LocalMapper& mapper;
  loop::LoopCloser& closer;
  RunRecorder& recorder;
  tracking::ImuShiftRamp& imu_shift;
  std::uint64_t& imu_generation;
};

/// The run section's bytes: the atlas part (with `header` and every culled keyframe the stages
/// hold), then the stages' parts. `settings_fingerprint` identifies the settings (runStateFingerprint).
std::string writeRunState(map::Atlas& atlas, const map::RunStateHeader& header, std::uint64_t settings_fingerprint,
                          const RunStages& stages);

/// Restores the stages' parts of a loaded run state (its atlas part is applied by map::loadAtlas)
/// on stages built with the saved run's settings in the loaded atlas, before its first frame.
/// Returns the saved run's settings fingerprint (a difference makes the continuation inexact: the
/// caller warns). Throws AtlasFileError naming the file, the section "run" and the byte.
std::uint64_t readRunState(const map::LoadedRunState& run, const RunStages& stages);

/// FNV-1a 64 of a settings description without its file names (Settings::describe()'s settings,
/// calibration and --set lines: the values they gave follow), and the switches of the run.
std::uint64_t runStateFingerprint(const std::string& settings_description, bool use_imu, bool oracle_masks);

}  // namespace ltlo::system
