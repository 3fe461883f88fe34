#include "png_decode.h"

#include <libdeflate.h>

#include <cstdio>
#include <cstring>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <vector>

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "16-bit PNG samples are swapped to host");

namespace ltlo::io {
namespace {

// PNG specification (ISO/IEC 15948): file signature, chunk layout (length, type, data, CRC-32 of
// type and data), IHDR fields, and the five per-row filter types.
constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
// Larger images (filtered data beyond this many bytes) are left to cv::imread and its limits.
constexpr std::size_t kMaxFilteredBytes = std::size_t{1} << 29;
// Deflate expands at most 1032-fold: a header announcing more than that of its data is a lie
// (declined before anything is allocated for it).
constexpr std::size_t kMaxInflateRatio = 1032;
// Per-thread buffers beyond this size are released after use (the sequences need about 1 MB).
constexpr std::size_t kKeptBufferBytes = std::size_t{64} << 20;

uint32_t bigEndian32(const unsigned char* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | uint32_t{p[3]};
}

bool chunkIs(const unsigned char* type, const char* name) {
  return std::memcmp(type, name, 4) == 0;
}

// Chunks that do not change what cv::imread returns with IMREAD_UNCHANGED.
bool harmlessAncillary(const unsigned char* type) {
  return chunkIs(type, "tEXt") || chunkIs(type, "zTXt") || chunkIs(type, "iTXt") ||
         chunkIs(type, "tIME") || chunkIs(type, "pHYs");
}

struct DecompressorDeleter {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

// Per-thread reusable state: no allocation per image once the buffers have grown.
struct ThreadBuffers {
  std::unique_ptr<libdeflate_decompressor, DecompressorDeleter> decompressor{
      libdeflate_alloc_decompressor()};
  std::vector<unsigned char> file;
  std::vector<unsigned char> compressed;  // IDAT data when split over several chunks
  std::vector<unsigned char> filtered;    // inflated: per row a filter byte and the row
};

void releaseIfLarge(std::vector<unsigned char>* buffer) {
  if (buffer->capacity() > kKeptBufferBytes) std::vector<unsigned char>().swap(*buffer);
}

// The decoder's own buffers (not `file`, which may hold the data being decoded).
void releaseLargeBuffers(ThreadBuffers* buffers) {
  releaseIfLarge(&buffers->compressed);
  releaseIfLarge(&buffers->filtered);
}

ThreadBuffers& threadBuffers() {
  thread_local ThreadBuffers buffers;
  return buffers;
}

int paeth(int a, int b, int c) {
  const int p = a + b - c;
  const int pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  if (pa <= pb && pa <= pc) return a;
  return pb <= pc ? b : c;
}

// The Sub filter's inverse for `kBpp` bytes per pixel: one running sum per byte lane, kept in
// registers (a loop over dst[i - bpp] waits on a store per byte).
template <int kBpp>
void unfilterSub(const unsigned char* src, unsigned char* dst, std::size_t n) {
  unsigned char sum[kBpp] = {};
  for (std::size_t i = 0; i + kBpp <= n; i += kBpp) {
    for (int k = 0; k < kBpp; ++k) {
      sum[k] = static_cast<unsigned char>(sum[k] + src[i + k]);
      dst[i + k] = sum[k];
    }
  }
}

// Undoes one row's filter into `dst`; `prev` is the previous reconstructed row (nullptr on the
// first row: zeros). `bpp` is bytes per complete pixel (at least 1).
bool unfilterRow(int filter, const unsigned char* src, const unsigned char* prev,
                 unsigned char* dst, std::size_t n, std::size_t bpp) {
  switch (filter) {
    case 0:
      std::memcpy(dst, src, n);
      return true;
    case 1:
      // n is a multiple of bpp; the sequences' depth (2) and colour (3) rows are Sub-filtered.
      if (bpp == 1) return unfilterSub<1>(src, dst, n), true;
      if (bpp == 2) return unfilterSub<2>(src, dst, n), true;
      if (bpp == 3) return unfilterSub<3>(src, dst, n), true;
      if (bpp == 4) return unfilterSub<4>(src, dst, n), true;
      for (std::size_t i = 0; i < bpp && i < n; ++i) dst[i] = src[i];
      for (std::size_t i = bpp; i < n; ++i)
        dst[i] = static_cast<unsigned char>(src[i] + dst[i - bpp]);
      return true;
    case 2:
      if (prev == nullptr) {
        std::memcpy(dst, src, n);
      } else {
        for (std::size_t i = 0; i < n; ++i) dst[i] = static_cast<unsigned char>(src[i] + prev[i]);
      }
      return true;
    case 3:
      for (std::size_t i = 0; i < n; ++i) {
        const int a = i >= bpp ? dst[i - bpp] : 0;
        const int b = prev != nullptr ? prev[i] : 0;
        dst[i] = static_cast<unsigned char>(src[i] + ((a + b) >> 1));
      }
      return true;
    case 4:
      for (std::size_t i = 0; i < n; ++i) {
        const int a = i >= bpp ? dst[i - bpp] : 0;
        const int b = prev != nullptr ? prev[i] : 0;
        const int c = prev != nullptr && i >= bpp ? prev[i - bpp] : 0;
        dst[i] = static_cast<unsigned char>(src[i] + paeth(a, b, c));
      }
      return true;
    default:
      return false;
  }
}

}  // namespace

bool decodePngFast(const unsigned char* data, std::size_t size, cv::Mat* out) {
  if (size < 8 + 25 || std::memcmp(data, kSignature, 8) != 0) return false;
  ThreadBuffers& buffers = threadBuffers();
  if (!buffers.decompressor) return false;

  uint32_t width = 0, height = 0;
  int bit_depth = 0, colour_type = -1;
  const unsigned char* idat = nullptr;  // the single IDAT's data, or nullptr when split
  std::size_t idat_size = 0;
  int idat_chunks = 0;
  bool ended = false;
  buffers.compressed.clear();
  for (std::size_t p = 8; !ended;) {
    if (size - p < 12) return false;
    const uint32_t length = bigEndian32(data + p);
    if (length > 0x7fffffffu || size - p - 12 < length) return false;
    const unsigned char* type = data + p + 4;
    const unsigned char* body = data + p + 8;
#ifndef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION  // fuzzers reach the pixel code past the CRC
    if (libdeflate_crc32(0, type, length + 4) != bigEndian32(body + length)) return false;
#endif
    if (p == 8) {  // IHDR first: width, height, bit depth, colour type, method, filter, interlace
      if (!chunkIs(type, "IHDR") || length != 13) return false;
      width = bigEndian32(body);
      height = bigEndian32(body + 4);
      bit_depth = body[8];
      colour_type = body[9];
      if (body[10] != 0 || body[11] != 0 || body[12] != 0) return false;  // interlaced, unknown
    } else if (chunkIs(type, "IDAT")) {
      if (idat_chunks == 1) buffers.compressed.assign(idat, idat + idat_size);
      if (idat_chunks >= 1)
        buffers.compressed.insert(buffers.compressed.end(), body, body + length);
      idat = body;
      idat_size = length;
      ++idat_chunks;
    } else if (chunkIs(type, "IEND")) {
      ended = true;
    } else if (!harmlessAncillary(type)) {
      return false;  // palette, transparency, gamma, colour profile, ...: cv::imread decides
    }
    p += 12 + std::size_t{length};
  }
  int channels = 0;
  if (colour_type == 0) channels = 1;
  if (colour_type == 2) channels = 3;
  if (colour_type == 6) channels = 4;
  if (channels == 0 || (bit_depth != 8 && bit_depth != 16) || idat_chunks == 0 || width == 0 ||
      height == 0 || width > 0x7fffffffu / 8 || height > 0x7fffffffu) {
    return false;
  }
  const std::size_t bytes_per_sample = bit_depth / 8;
  const std::size_t bpp = bytes_per_sample * channels;
  const std::size_t row_bytes = bpp * width;
  const std::size_t filtered_bytes = (row_bytes + 1) * height;
  if (filtered_bytes > kMaxFilteredBytes) return false;

  const unsigned char* compressed = idat_chunks == 1 ? idat : buffers.compressed.data();
  const std::size_t compressed_size = idat_chunks == 1 ? idat_size : buffers.compressed.size();
  if (filtered_bytes / kMaxInflateRatio > compressed_size) return false;
  buffers.filtered.resize(filtered_bytes);
  std::size_t inflated = 0;
  const bool inflated_all =
      libdeflate_zlib_decompress(buffers.decompressor.get(), compressed, compressed_size,
                                 buffers.filtered.data(), filtered_bytes,
                                 &inflated) == LIBDEFLATE_SUCCESS &&
      inflated == filtered_bytes;
  if (!inflated_all) {
    releaseLargeBuffers(&buffers);
    return false;
  }

  cv::Mat image(static_cast<int>(height), static_cast<int>(width),
                CV_MAKETYPE(bit_depth == 8 ? CV_8U : CV_16U, channels));
  for (uint32_t y = 0; y < height; ++y) {
    const unsigned char* src = buffers.filtered.data() + y * (row_bytes + 1);
    const unsigned char* prev = y > 0 ? image.ptr<unsigned char>(static_cast<int>(y) - 1) : nullptr;
    if (!unfilterRow(src[0], src + 1, prev, image.ptr<unsigned char>(static_cast<int>(y)),
                     row_bytes, bpp)) {
      return false;
    }
  }
  // PNG stores RGB(A) big-endian; cv::imread gives BGR(A) in host order.
  const std::size_t samples = static_cast<std::size_t>(width) * height * channels;
  if (bit_depth == 16) {
    uint16_t* s = image.ptr<uint16_t>();
    for (std::size_t k = 0; k < samples; ++k)
      s[k] = static_cast<uint16_t>((s[k] >> 8) | (s[k] << 8));
    if (channels >= 3) {
      for (std::size_t k = 0; k < samples; k += channels) std::swap(s[k], s[k + 2]);
    }
  } else if (channels >= 3) {
    unsigned char* s = image.ptr<unsigned char>();
    for (std::size_t k = 0; k < samples; k += channels) std::swap(s[k], s[k + 2]);
  }
  *out = image;
  releaseLargeBuffers(&buffers);
  return true;
}

cv::Mat readImageUnchanged(const std::string& path) {
  ThreadBuffers& buffers = threadBuffers();
  if (std::FILE* file = std::fopen(path.c_str(), "rb")) {
    bool read = std::fseek(file, 0, SEEK_END) == 0;
    const long size = read ? std::ftell(file) : -1;
    read = read && size > 0 && std::fseek(file, 0, SEEK_SET) == 0;
    if (read) {
      buffers.file.resize(static_cast<std::size_t>(size));
      read = std::fread(buffers.file.data(), 1, buffers.file.size(), file) == buffers.file.size();
    }
    std::fclose(file);
    cv::Mat image;
    const bool decoded = read && decodePngFast(buffers.file.data(), buffers.file.size(), &image);
    releaseIfLarge(&buffers.file);
    if (decoded) return image;
  }
  return cv::imread(path, cv::IMREAD_UNCHANGED);
}

}  // namespace ltlo::io
