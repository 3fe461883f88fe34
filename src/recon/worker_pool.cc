#include "worker_pool.h"

#include <string>

#include "ltlo/core/log.h"

namespace ltlo::recon {

namespace {
void range(int n, int parts, int part, int* begin, int* end) {
  *begin = static_cast<int>(static_cast<long>(n) * part / parts);
  *end = static_cast<int>(static_cast<long>(n) * (part + 1) / parts);
}
}  // namespace

WorkerPool::WorkerPool(int extra_threads) {
  for (int t = 0; t < extra_threads; ++t) {
    workers_.emplace_back([this, t] {
      log::setThreadName("fusion" + std::to_string(t + 1));
      work(t + 1);
    });
  }
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  start_.notify_all();
  for (std::thread& worker : workers_) worker.join();
}

void WorkerPool::work(int part) {
  long seen_generation = 0;
  for (;;) {
    const std::function<void(int, int, int)>* job = nullptr;
    int n = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      start_.wait(lock, [&] { return stopping_ || generation_ != seen_generation; });
      if (stopping_) return;
      seen_generation = generation_;
      job = job_;
      n = n_;
    }
    std::exception_ptr error;
    try {
      int begin = 0, end = 0;
      range(n, parts(), part, &begin, &end);
      if (begin < end) (*job)(begin, end, part);
    } catch (...) {
      error = std::current_exception();
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (error && !error_) error_ = error;
      --pending_;
    }
    done_.notify_one();
  }
}

void WorkerPool::parallelFor(int n, const std::function<void(int, int, int)>& f) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    job_ = &f;
    n_ = n;
    pending_ = static_cast<int>(workers_.size());
    error_ = nullptr;
    ++generation_;
  }
  start_.notify_all();
  std::exception_ptr error;
  try {
    int begin = 0, end = 0;
    range(n, parts(), 0, &begin, &end);
    if (begin < end) f(begin, end, 0);
  } catch (...) {
    error = std::current_exception();
  }
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [&] { return pending_ == 0; });
  if (!error) error = error_;
  job_ = nullptr;
  lock.unlock();
  if (error) std::rethrow_exception(error);
}

}  // namespace ltlo::recon
