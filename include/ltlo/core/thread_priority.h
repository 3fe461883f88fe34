#pragma once
/// Background threads' scheduling priority. On 2 cores the SLAM threads (tracking, local mapping,
/// loop closing, the segmentation worker) keep both busy; a thread whose work may be dropped when it
/// falls behind (the live viewer: rendering, JPEG and video encoding) runs at a lower priority so it
/// takes the time they leave instead of sharing it with them.
namespace ltlo {

/// Raises the calling thread's nice value by `increment` (Linux: per thread, setpriority on its
/// thread id; 0 does nothing). Returns the new nice value, or the unchanged one when the system
/// refuses (never an error: the thread then simply runs at its old priority).
int lowerCurrentThreadPriority(int increment);

/// The calling thread's nice value.
int currentThreadNice();

}  // namespace ltlo
