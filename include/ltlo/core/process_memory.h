#pragma once
/// Memory of this process, for run summaries, metrics.json and the mapping timeline.

namespace ltlo {

/// Peak resident set size of this process so far, MB (getrusage ru_maxrss). 0 when unavailable.
double peakResidentMb();

/// Resident set size of this process now, MB (/proc/self/statm). 0 when unavailable. One short
/// file read: cheap enough per keyframe, not per pixel.
double currentResidentMb();

}  // namespace ltlo
