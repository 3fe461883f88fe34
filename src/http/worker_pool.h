#pragma once
/// The connection threads of MjpegServer: httplib's TaskQueue interface over a fixed pool whose
/// threads carry the project's thread name ("ltlo.http"), so runningNamedThreads() sees them and
/// a test can check that stop() left none.
#include <httplib.h>

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace ltlo::http {

/// A fixed number of threads running queued connection jobs in order. Jobs beyond the thread
/// count wait in the queue (unbounded, as httplib's own pool). shutdown() runs the queued jobs
/// (they close their sockets), then joins. Thread-safe.
class WorkerPool final : public httplib::TaskQueue {
 public:
  explicit WorkerPool(int num_threads);
  ~WorkerPool() override;  ///< shutdown() unless done
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  void enqueue(std::function<void()> job) override;
  void shutdown() override;

 private:
  void run();

  std::mutex mutex_;  // guards jobs_, shutting_down_
  std::condition_variable job_or_shutdown_;
  std::deque<std::function<void()>> jobs_;
  bool shutting_down_ = false;
  std::vector<std::thread> threads_;  // touched by the constructor and shutdown() only
};

}  // namespace ltlo::http
