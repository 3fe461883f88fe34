#pragma once
// Loads chosen frames of a sequence (PNG decoding is most of an offline fusion's time) in several
// threads and hands them out in order, at most `lookahead` frames ahead of the consumer.
//
//   ParallelFrameLoader frames(reader, indices, {}, /*num_threads=*/2, /*lookahead=*/6);
//   while (std::optional<io::RgbdImuFrame> f = frames.next()) fuse(*f);  // rethrows read errors
//
// Threads: the workers only call the reader's const, thread-safe load(); the reader must outlive
// the loader. next() is for one consumer. The destructor stops and joins the workers.
#include <condition_variable>
#include <cstdint>
#include <cstddef>
#include <exception>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <variant>
#include <vector>

#include "ltlo/io/sequence_reader.h"

namespace ltlo::recon {

class ParallelFrameLoader {
 public:
  /// `with_colour[k]` (same length as indices, or empty = all) says whether frame indices[k] is
  /// loaded with its colour image.
  ParallelFrameLoader(const io::SequenceReader& reader, std::vector<int> indices,
                      std::vector<uint8_t> with_colour, int num_threads, int lookahead);
  ~ParallelFrameLoader();
  ParallelFrameLoader(const ParallelFrameLoader&) = delete;
  ParallelFrameLoader& operator=(const ParallelFrameLoader&) = delete;

  /// The next frame of `indices`, in order; nullopt after the last. A frame that failed to load
  /// rethrows its exception here (InputError naming the file).
  std::optional<io::RgbdImuFrame> next();

 private:
  using Result = std::variant<io::RgbdImuFrame, std::exception_ptr>;
  void work();

  const io::SequenceReader& reader_;
  const std::vector<int> indices_;
  const std::vector<uint8_t> with_colour_;
  const std::size_t lookahead_;
  std::mutex mutex_;                  // guards everything below
  std::condition_variable may_load_;  // a slot in the lookahead window freed, or stopping
  std::condition_variable loaded_;    // a frame was stored in done_
  std::size_t next_job_ = 0;          // position in indices_ the next worker loads
  std::size_t next_out_ = 0;          // position next() delivers
  std::map<std::size_t, Result> done_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace ltlo::recon
