#include "parallel_frame_loader.h"

#include <chrono>
#include <string>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"

namespace ltlo::recon {

FusionFrame toFusionFrame(const io::RgbdImuFrame& frame, const SE3& T_w_c) {
  FusionFrame input;
  input.t_s = frame.t_s;
  input.T_w_c = T_w_c;
  input.depth_m = frame.depth_m;
  input.colour_bgr = frame.color_bgr;
  input.dynamic_mask = frame.mask;
  return input;
}

ParallelFrameLoader::ParallelFrameLoader(const io::SequenceReader& reader, std::vector<int> indices,
                                         std::vector<uint8_t> with_colour, int num_threads,
                                         int lookahead, const SurfelFusion* preparer,
                                         const Undistorter* undistorter)
    : reader_(reader),
      indices_(std::move(indices)),
      with_colour_(std::move(with_colour)),
      lookahead_(static_cast<std::size_t>(lookahead)),
      preparer_(preparer),
      undistorter_(undistorter) {
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
      LoadedFrame loaded;
      loaded.frame = reader_.load(indices_[job], with_colour_.empty() || with_colour_[job] != 0);
      if (undistorter_ != nullptr && undistorter_->active()) {
        io::RgbdImuFrame& f = loaded.frame;
        cv::Mat ideal;
        if (!f.color_bgr.empty()) {
          undistorter_->toIdeal(f.color_bgr, &ideal, cv::INTER_LINEAR);
          f.color_bgr = ideal;
        }
        if (!f.depth_m.empty()) {
          undistorter_->toIdeal(f.depth_m, &ideal, cv::INTER_NEAREST);
          f.depth_m = ideal;
        }
        if (!f.mask.empty()) {
          undistorter_->toIdeal(f.mask, &ideal, cv::INTER_NEAREST);
          f.mask = ideal;
        }
      }
      if (preparer_ != nullptr) {
        {
          std::lock_guard<std::mutex> lock(mutex_);
          if (!spare_.empty()) {
            loaded.prepared = std::move(spare_.back());
            spare_.pop_back();
          }
        }
        const auto start = std::chrono::steady_clock::now();
        preparer_->prepare(toFusionFrame(loaded.frame, SE3()), &loaded.prepared);
        loaded.prepare_s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      }
      result = std::move(loaded);
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

std::optional<LoadedFrame> ParallelFrameLoader::next() {
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
  return std::move(std::get<LoadedFrame>(result));
}

void ParallelFrameLoader::recycle(PreparedFrame&& prepared) {
  std::lock_guard<std::mutex> lock(mutex_);
  spare_.push_back(std::move(prepared));
}

}  // namespace ltlo::recon
