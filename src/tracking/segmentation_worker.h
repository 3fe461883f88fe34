#pragma once
// SegmentationWorker: the persistent thread a FrameSegmenter runs its image work on (depth
// clustering, pyramid) while the tracking thread extracts ORB features. One job at a time:
//   post(input)   tracking thread: hands the frame to the worker, returns at once;
//   wait()        tracking thread: blocks (condition variable) until the job is done, rethrows
//                 an exception the job threw.
// The thread is started by the constructor and joined by the destructor; no thread per frame.
// The job reads the input frame and writes only the segmenter's buffers for the frame being
// prepared; the tracking thread touches those only after wait() returned.
#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

#include "ltlo/io/sequence_reader.h"

namespace ltlo::tracking {

class SegmentationWorker {
 public:
  using Job = std::function<void(const io::RgbdImuFrame&)>;
  /// Starts the thread; `job` runs on it once per post().
  explicit SegmentationWorker(Job job);
  /// Waits for a running job, stops and joins the thread.
  ~SegmentationWorker();
  SegmentationWorker(const SegmentationWorker&) = delete;
  SegmentationWorker& operator=(const SegmentationWorker&) = delete;

  /// Starts the job on `input` (must stay alive until wait() returns). Asserts no job is pending.
  void post(const io::RgbdImuFrame& input);
  /// Blocks until the posted job finished (returns at once when none is pending); rethrows what the
  /// job threw.
  void wait();
  /// Whether a job was posted and not yet waited for.
  bool pending() const { return pending_; }

 private:
  void run();

  Job job_;
  std::mutex mutex_;
  std::condition_variable wake_;  // a job posted, or stop
  std::condition_variable done_;  // the job finished
  const io::RgbdImuFrame* input_ = nullptr;  // guarded by mutex_; null = no job queued
  bool running_job_ = false;                 // guarded by mutex_
  bool stop_ = false;                        // guarded by mutex_
  std::exception_ptr error_;                 // guarded by mutex_
  bool pending_ = false;                     // tracking thread only
  std::thread thread_;                       // last member: started when the rest exists
};

}  // namespace ltlo::tracking
