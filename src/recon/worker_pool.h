#pragma once
// A fixed set of worker threads that split loops with the calling thread: the fusion's per-frame
// stages run on both cores without starting threads per frame.
//
//   WorkerPool pool(/*extra_threads=*/1);
//   pool.parallelFor(height, [&](int begin, int end, int part) { for (...) rows begin..end-1 });
//
// Threads: parallelFor() is called by one thread at a time (the owner); it returns when every
// part is done, so the parts may use the caller's data by reference. The destructor joins.
#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace ltlo::recon {

class WorkerPool {
 public:
  explicit WorkerPool(int extra_threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  /// Number of parts a loop is split into (extra threads + the caller).
  int parts() const { return static_cast<int>(workers_.size()) + 1; }

  /// Calls f(begin, end, part) for parts() consecutive ranges covering [0, n) (part 0 on the
  /// calling thread); rethrows the first exception of a part.
  void parallelFor(int n, const std::function<void(int begin, int end, int part)>& f);

 private:
  void work(int part);

  std::vector<std::thread> workers_;
  std::mutex mutex_;  // guards everything below
  std::condition_variable start_;
  std::condition_variable done_;
  const std::function<void(int, int, int)>* job_ = nullptr;
  int n_ = 0;
  long generation_ = 0;  // incremented per parallelFor: workers run each generation once
  int pending_ = 0;      // workers still running the current generation
  std::exception_ptr error_;
  bool stopping_ = false;
};

}  // namespace ltlo::recon
