#pragma once
// Loads chosen frames of a sequence (PNG decoding is most of an offline fusion's time) in several
// threads and hands them out in order, at most `lookahead` frames ahead of the consumer. Given a
// SurfelFusion, the loader threads also measure each frame (SurfelFusion::prepare), which does
// not depend on the model: the fusing thread then only does the model's stages.
//
//   ParallelFrameLoader frames(reader, indices, {}, /*num_threads=*/2, /*lookahead=*/6, &fusion);
//   while (std::optional<LoadedFrame> f = frames.next()) {  // rethrows read errors
//     fusion.integrate(toFusionFrame(f->frame), f->prepared);
//     frames.recycle(std::move(f->prepared));               // its buffers serve a later frame
//   }
//
// Threads: the workers only call the reader's const, thread-safe load() and the fusion's const,
// thread-safe prepare(); the reader and fusion must outlive the loader. next() and recycle() are
// for one consumer. The destructor stops and joins the workers.
//
// With a distorting lens (an active `undistorter`) each loaded frame's colour (bilinear), depth and
// mask (nearest) are remapped onto the ideal pinhole grid in the loader thread, before it is
// measured: the fusion sees an ideal camera of the same K.
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

#include "ltlo/core/undistorter.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/recon/surfel_fusion.h"

namespace ltlo::recon {

struct LoadedFrame {
  io::RgbdImuFrame frame;
  PreparedFrame prepared;     ///< measured when the loader has a fusion; else empty
  double prepare_s = 0.0;     ///< time the loader thread spent measuring it
};

/// The frame as SurfelFusion input (images shared, not copied) at pose T_w_c.
FusionFrame toFusionFrame(const io::RgbdImuFrame& frame, const SE3& T_w_c);

class ParallelFrameLoader {
 public:
  /// `with_colour[k]` (same length as indices, or empty = all) says whether frame indices[k] is
  /// loaded with its colour image. `preparer` (may be null) measures every loaded frame.
  ParallelFrameLoader(const io::SequenceReader& reader, std::vector<int> indices,
                      std::vector<uint8_t> with_colour, int num_threads, int lookahead,
                      const SurfelFusion* preparer = nullptr, const Undistorter* undistorter = nullptr);
  ~ParallelFrameLoader();
  ParallelFrameLoader(const ParallelFrameLoader&) = delete;
  ParallelFrameLoader& operator=(const ParallelFrameLoader&) = delete;

  /// The next frame of `indices`, in order; nullopt after the last. A frame that failed to load
  /// rethrows its exception here (InputError naming the file).
  std::optional<LoadedFrame> next();

  /// Gives a used PreparedFrame back; a loader thread prepares a later frame in its buffers.
  void recycle(PreparedFrame&& prepared);

 private:
  using Result = std::variant<LoadedFrame, std::exception_ptr>;
  void work();

  const io::SequenceReader& reader_;
  const std::vector<int> indices_;
  const std::vector<uint8_t> with_colour_;
  const std::size_t lookahead_;
  const SurfelFusion* const preparer_;
  const Undistorter* const undistorter_;
  std::mutex mutex_;                  // guards everything below
  std::condition_variable may_load_;  // a slot in the lookahead window freed, or stopping
  std::condition_variable loaded_;    // a frame was stored in done_
  std::size_t next_job_ = 0;          // position in indices_ the next worker loads
  std::size_t next_out_ = 0;          // position next() delivers
  std::map<std::size_t, Result> done_;
  std::vector<PreparedFrame> spare_;  // recycled measurement buffers
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace ltlo::recon
