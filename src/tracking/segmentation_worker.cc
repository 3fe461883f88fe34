#include "segmentation_worker.h"

#include <utility>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"

namespace ltlo::tracking {

SegmentationWorker::SegmentationWorker(Job job) : job_(std::move(job)), thread_([this] { run(); }) {}

SegmentationWorker::~SegmentationWorker() {
  {
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return input_ == nullptr && !running_job_; });
    stop_ = true;
  }
  wake_.notify_one();
  thread_.join();
}

void SegmentationWorker::post(const io::RgbdImuFrame& input) {
  LTLO_ASSERT(!pending_, "SegmentationWorker::post while a job is pending");
  {
    std::lock_guard<std::mutex> lock(mutex_);
    input_ = &input;
    error_ = nullptr;
  }
  pending_ = true;
  wake_.notify_one();
}

void SegmentationWorker::wait() {
  if (!pending_) return;
  std::exception_ptr error;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return input_ == nullptr && !running_job_; });
    error = std::exchange(error_, nullptr);
  }
  pending_ = false;
  if (error) std::rethrow_exception(error);
}

void SegmentationWorker::run() {
  log::setThreadName("segmentation");
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    wake_.wait(lock, [this] { return stop_ || input_ != nullptr; });
    if (input_ == nullptr) return;  // stop with nothing queued
    const io::RgbdImuFrame& input = *input_;
    running_job_ = true;
    lock.unlock();
    std::exception_ptr error;
    try {
      job_(input);
    } catch (...) {
      error = std::current_exception();  // handed to the tracking thread by wait()
    }
    lock.lock();
    running_job_ = false;
    input_ = nullptr;
    error_ = error;
    done_.notify_all();
  }
}

}  // namespace ltlo::tracking
