#pragma once
/// SegmentationWriter: writes every frame's static/dynamic mask to RUN/segmentation/<timestamp>.png
/// (8-bit, 255 = dynamic, 0 = static, at the input resolution: DATA_FORMAT.md's masks/ convention)
/// on a thread of its own, so the tracking thread never waits for PNG encoding. Masks arrive at the
/// label resolution and are upsampled (nearest) on the writer thread. With a distorting lens the
/// labels lie on the ideal pinhole grid: each raw pixel then takes the label at its undistorted
/// position (Undistorter::rawToIdealMap, built once per label scale), so the files stay in the raw
/// image's grid, as the sequence's masks/ are.
///
/// Threads: push() from the tracking thread, the writer thread started by the constructor and
/// joined by finish() / the destructor; they share only the bounded queue. The queue holds
/// `capacity` masks (label resolution, 77 kB each at QVGA); push() waits only when the writer is
/// that far behind (a stalled disk), never for the encoding of the frame just pushed.
#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include <opencv2/core.hpp>

#include "ltlo/core/blocking_queue.h"
#include "ltlo/core/undistorter.h"

namespace ltlo::system {

/// Masks at the label resolution (CV_8U) onto the raw image's grid: with a distorting lens and the
/// camera's size, each raw pixel takes the label at its undistorted position (Undistorter::rawToIdealMap,
/// built once per label scale); otherwise nearest upsampling. One per thread (it keeps its map).
class RawGridMasks {
 public:
  explicit RawGridMasks(std::shared_ptr<const Undistorter> undistorter) : undistorter_(std::move(undistorter)) {}
  /// `mask` at width x height: `mask` itself when it is that size and no lens applies, else `*scratch`.
  const cv::Mat& toRaw(const cv::Mat& mask, int width, int height, cv::Mat* scratch);

 private:
  std::shared_ptr<const Undistorter> undistorter_;
  cv::Mat raw_to_ideal_;  // rawToIdealMap of raw_to_ideal_scale_
  int raw_to_ideal_scale_ = 0;
};

class SegmentationWriter {
 public:
  /// Creates `dir` (throws InputError when it cannot) and starts the writer thread.
  explicit SegmentationWriter(std::string dir, std::size_t capacity = 128,
                              std::shared_ptr<const Undistorter> undistorter = nullptr);
  /// finish()
  ~SegmentationWriter();
  SegmentationWriter(const SegmentationWriter&) = delete;
  SegmentationWriter& operator=(const SegmentationWriter&) = delete;

  /// Queues `mask` (CV_8U, 255 = dynamic) to be written as <name>.png at width x height.
  void push(std::string name, cv::Mat mask, int width, int height);
  /// Writes what is queued and joins the thread (idempotent). Returns the number of files written.
  int finish();
  /// Files written so far.
  int written() const { return written_.load(); }
  /// The file name stem of a frame: the stem of its colour image when that is a timestamp (so the
  /// names match the sequence's masks/), else t_s with 6 decimals.
  static std::string frameName(const std::string& color_path, double t_s);

 private:
  struct Item {
    std::string name;
    cv::Mat mask;
    int width = 0;
    int height = 0;
  };
  void run();

  std::string dir_;
  RawGridMasks raw_grid_;  // writer thread only
  BlockingQueue<Item> queue_;
  std::atomic<int> written_{0};
  bool failed_ = false;  // writer thread only: stop writing after the first failure
  bool finished_ = false;
  std::thread thread_;
};

}  // namespace ltlo::system
