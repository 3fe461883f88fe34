#pragma once
// Image files read as cv::imread(path, cv::IMREAD_UNCHANGED) does, with a faster path for the
// PNGs of RGB-D sequences: decoding them is most of an offline reconstruction's CPU time, and
// the tracking thread's input cost on a live run.
//
//   cv::Mat depth = io::readImageUnchanged("seq/depth/0.000000.png");  // CV_16UC1
//
// Fast path: non-interlaced 8- or 16-bit grey, RGB or RGBA PNGs whose only other chunks are text,
// time or pixel size (nothing that changes the pixels), inflated by libdeflate with every chunk
// CRC and the zlib Adler-32 checked. Everything else (other formats and PNG variants, damaged
// files) goes through cv::imread, so results and failures are those of cv::imread. Thread-safe:
// its reusable buffers are per thread.
#include <opencv2/core/mat.hpp>
#include <string>

namespace ltlo::io {

/// The image at `path` like cv::imread(path, cv::IMREAD_UNCHANGED): BGR(A) channel order,
/// 16-bit samples in host order; an empty Mat when the file cannot be read or decoded (cv::imread
/// may also throw cv::Exception, as before).
cv::Mat readImageUnchanged(const std::string& path);

/// The fast path alone on a file's bytes: false (and `out` untouched) when the data is not a PNG
/// it handles, is damaged, or does not decode to exactly the announced size.
bool decodePngFast(const unsigned char* data, std::size_t size, cv::Mat* out);

}  // namespace ltlo::io
