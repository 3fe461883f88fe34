// LoopCloser's state between two keyframes in the atlas file's run state (ltlo/map/run_state_io.h,
// system/run_state.h): the loop and merge candidates' consistency, the map they belong to, the
// keyframes since the last correction, the pending refining (or waiting) full BA and the full BAs'
// budget (Loop.FullBaBudget). The events and their counts
// are statistics and stay this run's.
#include <limits>
#include <string>

#include "loop_closer_impl.h"
#include "ltlo/map/binary_io.h"

namespace ltlo::loop {

void LoopCloser::writeState(map::ByteWriter& out) const {
  const Impl& impl = *impl_;
  LTLO_ASSERT(impl.queue.size() == 0 && !globalBaRunning(), "loop closing's state saved while it works");
  impl.detector.writeState(out);
  impl.merge_consistency.writeState(out);
  out.u64(impl.detection_map.value);
  out.i32(impl.keyframes_since_correction);
  out.u64(impl.refine_map.value);
  out.boolean(impl.refine_pending);
  out.u64(impl.keyframes_received);
  out.u64(impl.full_ba_keyframes);
}

void LoopCloser::readState(map::ByteReader& in) {
  Impl& impl = *impl_;
  impl.detector.readState(in);
  impl.merge_consistency.readState(in);
  impl.detection_map = map::MapId(in.u64("loop detection map"));
  impl.keyframes_since_correction =
      in.i32InRange("keyframes since the correction", 0, std::numeric_limits<std::int32_t>::max());
  impl.refine_map = map::MapId(in.u64("map to refine"));
  impl.refine_pending = in.boolean("refinement pending");
  impl.keyframes_received = in.u64("keyframes received");
  impl.full_ba_keyframes = in.u64("keyframes of full BAs");
}

}  // namespace ltlo::loop
