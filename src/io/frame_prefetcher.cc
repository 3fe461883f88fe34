#include "ltlo/io/frame_prefetcher.h"

#include <utility>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"

namespace ltlo::io {

FramePrefetcher::FramePrefetcher(SequenceReader& reader, std::size_t depth, long max_frames) : queue_(depth) {
  LTLO_ASSERT(depth >= 1, "prefetch depth must be at least 1");
  thread_ = std::thread([this, &reader, max_frames] { readLoop(reader, max_frames); });
}

FramePrefetcher::~FramePrefetcher() { stop(); }

void FramePrefetcher::readLoop(SequenceReader& reader, long max_frames) {
  log::setThreadName("reader");
  long read = 0;
  while (max_frames <= 0 || read < max_frames) {
    std::optional<RgbdImuFrame> frame;
    try {
      frame = reader.next();
    } catch (...) {
      queue_.push(std::current_exception());  // delivered after the frames before it
      return;
    }
    if (!frame) break;
    ++read;
    if (!queue_.push(std::move(*frame))) return;  // stopped
  }
  queue_.push(EndOfSequence{});
}

std::optional<RgbdImuFrame> FramePrefetcher::next() {
  if (ended_) return std::nullopt;
  std::optional<Item> item = queue_.pop();
  if (!item || std::holds_alternative<EndOfSequence>(*item)) {
    ended_ = true;
    return std::nullopt;
  }
  if (auto* error = std::get_if<std::exception_ptr>(&*item)) {
    ended_ = true;
    std::rethrow_exception(*error);
  }
  return std::move(std::get<RgbdImuFrame>(*item));
}

void FramePrefetcher::stop() {
  queue_.close();
  if (thread_.joinable()) thread_.join();
  ended_ = true;
}

}  // namespace ltlo::io
