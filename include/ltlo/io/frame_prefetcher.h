#pragma once
/// FramePrefetcher: reads a sequence one or more frames ahead in its own thread (PNG decoding and
/// IMU parsing overlap with the processing of the previous frame), in order.
///
///   io::FramePrefetcher frames(reader, 4);
///   while (std::optional<io::RgbdImuFrame> f = frames.next()) process(*f);   // rethrows read errors
///
/// Threads: the reader belongs to the prefetch thread from construction until stop() (or the
/// destructor) has joined it; the caller must not touch it in between. next() is for one consumer.
#include <cstddef>
#include <exception>
#include <optional>
#include <thread>
#include <variant>

#include "ltlo/core/blocking_queue.h"
#include "ltlo/io/sequence_reader.h"

namespace ltlo::io {

class FramePrefetcher {
 public:
  /// Starts reading `reader` from its current position, at most `depth` frames ahead (>= 1);
  /// `max_frames` > 0 stops after that many frames.
  FramePrefetcher(SequenceReader& reader, std::size_t depth, long max_frames = 0);
  FramePrefetcher(const FramePrefetcher&) = delete;
  FramePrefetcher& operator=(const FramePrefetcher&) = delete;
  ~FramePrefetcher();  ///< stop()

  /// The next frame in order; nullopt at the end of the sequence (or after stop()). An exception
  /// thrown by SequenceReader::next() (e.g. InputError naming the file) is rethrown here, in order:
  /// the frames read before it are delivered first.
  std::optional<RgbdImuFrame> next();

  /// Stops reading and joins the thread (idempotent); frames read ahead are dropped.
  void stop();

 private:
  struct EndOfSequence {};
  using Item = std::variant<RgbdImuFrame, std::exception_ptr, EndOfSequence>;

  void readLoop(SequenceReader& reader, long max_frames);

  BlockingQueue<Item> queue_;
  std::thread thread_;
  bool ended_ = false;
};

}  // namespace ltlo::io
