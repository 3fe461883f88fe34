#include "parallel_frame_loader.h"

#include <string>
#include <utility>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"

namespace ltlo::recon {

ParallelFrameLoader::ParallelFrameLoader(const io::SequenceReader& reader, std::vector<int> indices,
                                         std::vector<uint8_t> with_colour, int num_threads,
                                         int lookahead)
    : reader_(reader),
      indices_(std::move(indices)),
      with_colour_(std::move(with_colour)),
      lookahead_(static_cast<std::size_t>(lookahead)) {
  LTLO_ASSERT(num_threads >= 1 && lookahead >= 1,
              "loader threads " << num_threads << ", lookahead " << lookahead);
  for (int t = 0; t < num_threads; ++t) {
    threads_.emplace_back([this, t] {
      log::setThreadName("loader" + std::to_string(t));
      work();
    });
  }
}

ParallelFrameLoader::~ParallelFrameLoader() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  may_load_.notify_all();
  for (std::thread& thread : threads_) thread.join();
}

void ParallelFrameLoader::work() {
  for (;;) {
    std::size_t job = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      may_load_.wait(lock, [&] {
        return stopping_ || next_job_ >= indices_.size() || next_job_ < next_out_ + lookahead_;
      });
      if (stopping_ || next_job_ >= indices_.size()) return;
      job = next_job_++;
    }
    Result result;
    try {
      result = reader_.load(indices_[job], with_colour_.empty() || with_colour_[job] != 0);
    } catch (...) {
      result = std::current_exception();
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_.emplace(job, std::move(result));
    }
    loaded_.notify_all();
  }
}

std::optional<io::RgbdImuFrame> ParallelFrameLoader::next() {
  Result result;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    if (next_out_ >= indices_.size()) return std::nullopt;
    loaded_.wait(lock, [&] { return done_.count(next_out_) > 0; });
    auto it = done_.find(next_out_);
    result = std::move(it->second);
    done_.erase(it);
    ++next_out_;
  }
  may_load_.notify_all();
  if (auto* error = std::get_if<std::exception_ptr>(&result)) std::rethrow_exception(*error);
  return std::move(std::get<io::RgbdImuFrame>(result));
}

}  // namespace ltlo::recon
