#include "ltlo/system/segmentation_writer.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <utility>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"

namespace ltlo::system {

const cv::Mat& RawGridMasks::toRaw(const cv::Mat& mask, int width, int height, cv::Mat* scratch) {
  if (undistorter_ && undistorter_->active() && width == undistorter_->model().pinhole().width() &&
      height == undistorter_->model().pinhole().height() && width % mask.cols == 0) {
    const int scale = width / mask.cols;
    if (scale != raw_to_ideal_scale_) {
      raw_to_ideal_ = undistorter_->rawToIdealMap(scale);
      raw_to_ideal_scale_ = scale;
    }
    // Raw pixels whose ideal position lies beyond the label image take its border's label.
    cv::remap(mask, *scratch, raw_to_ideal_, cv::noArray(), cv::INTER_NEAREST, cv::BORDER_REPLICATE);
    return *scratch;
  }
  if (mask.cols != width || mask.rows != height) {
    cv::resize(mask, *scratch, cv::Size(width, height), 0.0, 0.0, cv::INTER_NEAREST);
    return *scratch;
  }
  return mask;
}

SegmentationWriter::SegmentationWriter(std::string dir, std::size_t capacity,
                                       std::shared_ptr<const Undistorter> undistorter)
    : dir_(std::move(dir)), raw_grid_(std::move(undistorter)), queue_(capacity) {
  std::error_code error;
  std::filesystem::create_directories(dir_, error);
  if (error) throw InputError(dir_, 0, "cannot create the segmentation folder: " + error.message());
  thread_ = std::thread([this] { run(); });
}

SegmentationWriter::~SegmentationWriter() { finish(); }

void SegmentationWriter::push(std::string name, cv::Mat mask, int width, int height) {
  queue_.push(Item{std::move(name), std::move(mask), width, height});
}

int SegmentationWriter::finish() {
  if (!finished_) {
    finished_ = true;
    queue_.close();
    if (thread_.joinable()) thread_.join();
  }
  return written_.load();
}

std::string SegmentationWriter::frameName(const std::string& color_path, double t_s) {
  const std::string stem = std::filesystem::path(color_path).stem().string();
  char* end = nullptr;
  const double value = stem.empty() ? 0.0 : std::strtod(stem.c_str(), &end);
  if (!stem.empty() && end != nullptr && *end == '\0' && std::isfinite(value)) return stem;
  char text[64];
  std::snprintf(text, sizeof(text), "%.6f", t_s);
  return text;
}

void SegmentationWriter::run() {
  log::setThreadName("seg-writer");
  cv::Mat full;
  while (std::optional<Item> item = queue_.pop()) {
    if (failed_) continue;  // drain after a failure
    const cv::Mat* image = &raw_grid_.toRaw(item->mask, item->width, item->height, &full);
    const std::string path = (std::filesystem::path(dir_) / (item->name + ".png")).string();
    bool ok = false;
    try {
      ok = cv::imwrite(path, *image);
    } catch (const cv::Exception& e) {
      log::error("segmentation writer: ", path, ": ", e.what());
    }
    if (!ok) {
      log::error("segmentation writer: cannot write ", path, "; no further masks are written");
      failed_ = true;
      continue;
    }
    written_.fetch_add(1);
  }
}

}  // namespace ltlo::system
