// The fast PNG path against cv::imread on PNGs written here with every filter type, bit depth and
// colour type it handles, split and single IDAT chunks; damaged and unhandled files fall back.
#include "png_decode.h"

#include <gtest/gtest.h>
#include <libdeflate.h>
#include <sys/resource.h>

#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

namespace ltlo::io {
namespace {

void put32(std::vector<unsigned char>* out, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8)
    out->push_back(static_cast<unsigned char>(v >> shift));
}

void putChunk(std::vector<unsigned char>* out, const char* type,
              const std::vector<unsigned char>& body) {
  put32(out, static_cast<uint32_t>(body.size()));
  std::vector<unsigned char> typed(type, type + 4);
  typed.insert(typed.end(), body.begin(), body.end());
  out->insert(out->end(), typed.begin(), typed.end());
  put32(out, libdeflate_crc32(0, typed.data(), typed.size()));
}

int paethPredictor(int a, int b, int c) {
  const int p = a + b - c;
  const int pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return pa <= pb && pa <= pc ? a : (pb <= pc ? b : c);
}

// A PNG of `rows` (raw big-endian RGB(A)/grey bytes per row) with row y filtered by filter
// (y + first_filter) % 5, the IDAT data split into `idat_chunks` chunks.
std::vector<unsigned char> encodePng(const std::vector<std::vector<unsigned char>>& rows, int width,
                                     int bit_depth, int colour_type, int bpp, int first_filter,
                                     int idat_chunks) {
  std::vector<unsigned char> filtered;
  for (std::size_t y = 0; y < rows.size(); ++y) {
    const int filter = static_cast<int>((y + first_filter) % 5);
    filtered.push_back(static_cast<unsigned char>(filter));
    const std::vector<unsigned char>& row = rows[y];
    for (std::size_t i = 0; i < row.size(); ++i) {
      const int a = i >= static_cast<std::size_t>(bpp) ? row[i - bpp] : 0;
      const int b = y > 0 ? rows[y - 1][i] : 0;
      const int c = y > 0 && i >= static_cast<std::size_t>(bpp) ? rows[y - 1][i - bpp] : 0;
      const int predictor[5] = {0, a, b, (a + b) >> 1, paethPredictor(a, b, c)};
      filtered.push_back(static_cast<unsigned char>(row[i] - predictor[filter]));
    }
  }
  libdeflate_compressor* compressor = libdeflate_alloc_compressor(6);
  std::vector<unsigned char> zlib(libdeflate_zlib_compress_bound(compressor, filtered.size()));
  zlib.resize(libdeflate_zlib_compress(compressor, filtered.data(), filtered.size(), zlib.data(),
                                       zlib.size()));
  libdeflate_free_compressor(compressor);

  std::vector<unsigned char> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<unsigned char> ihdr;
  put32(&ihdr, static_cast<uint32_t>(width));
  put32(&ihdr, static_cast<uint32_t>(rows.size()));
  ihdr.insert(ihdr.end(), {static_cast<unsigned char>(bit_depth),
                           static_cast<unsigned char>(colour_type), 0, 0, 0});
  putChunk(&png, "IHDR", ihdr);
  putChunk(&png, "tEXt", {'a', 0, 'b'});
  for (int k = 0; k < idat_chunks; ++k) {
    const std::size_t from = zlib.size() * k / idat_chunks,
                      to = zlib.size() * (k + 1) / idat_chunks;
    putChunk(&png, "IDAT", std::vector<unsigned char>(zlib.begin() + from, zlib.begin() + to));
  }
  putChunk(&png, "IEND", {});
  return png;
}

long peakRssKb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

class PngDecodeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("ltlo_png_decode_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::string write(const std::string& name, const std::vector<unsigned char>& bytes) {
    const std::string path = (dir_ / name).string();
    std::FILE* f = std::fopen(path.c_str(), "wb");
    std::fwrite(bytes.data(), 1, bytes.size(), f);
    std::fclose(f);
    return path;
  }

  std::filesystem::path dir_;
};

TEST_F(PngDecodeTest, EveryFilterDepthAndColourTypeDecodesLikeImread) {
  std::mt19937 rng(7);
  const int width = 37, height = 23;  // odd sizes: no accidental alignment
  struct Format {
    int bit_depth, colour_type, channels;
  };
  for (const Format& format : {Format{8, 0, 1}, Format{16, 0, 1}, Format{8, 2, 3}, Format{16, 2, 3},
                               Format{8, 6, 4}, Format{16, 6, 4}}) {
    const int bpp = format.channels * format.bit_depth / 8;
    std::vector<std::vector<unsigned char>> rows(height);
    for (int y = 0; y < height; ++y) {
      for (int i = 0; i < width * bpp; ++i) {  // a smooth ramp with noise: every filter matters
        rows[y].push_back(static_cast<unsigned char>(3 * i + 5 * y + rng() % 9));
      }
    }
    for (int first_filter = 0; first_filter < 5; ++first_filter) {
      for (int idat_chunks : {1, 3}) {
        SCOPED_TRACE("depth " + std::to_string(format.bit_depth) + " type " +
                     std::to_string(format.colour_type) + " first filter " +
                     std::to_string(first_filter) + " IDATs " + std::to_string(idat_chunks));
        const std::vector<unsigned char> png = encodePng(
            rows, width, format.bit_depth, format.colour_type, bpp, first_filter, idat_chunks);
        const std::string path = write("image.png", png);
        cv::Mat fast;
        ASSERT_TRUE(decodePngFast(png.data(), png.size(), &fast));
        const cv::Mat reference = cv::imread(path, cv::IMREAD_UNCHANGED);
        ASSERT_EQ(fast.type(), reference.type());
        ASSERT_EQ(fast.size(), reference.size());
        EXPECT_EQ(cv::norm(fast, reference, cv::NORM_INF), 0.0);
        EXPECT_EQ(cv::norm(readImageUnchanged(path), reference, cv::NORM_INF), 0.0);
      }
    }
  }
}

TEST_F(PngDecodeTest, OpenCvWrittenImagesRoundTrip) {
  cv::Mat depth(48, 64, CV_16UC1), colour(48, 64, CV_8UC3);
  cv::randu(depth, 0, 65535);
  cv::randu(colour, 0, 255);
  for (const cv::Mat& image : {depth, colour}) {
    const std::string path = (dir_ / "cv.png").string();
    ASSERT_TRUE(cv::imwrite(path, image));
    const cv::Mat decoded = readImageUnchanged(path);
    ASSERT_EQ(decoded.type(), image.type());
    EXPECT_EQ(cv::norm(decoded, image, cv::NORM_INF), 0.0);
  }
}

TEST_F(PngDecodeTest, DamagedOrUnhandledFilesAreLeftToImread) {
  std::vector<std::vector<unsigned char>> rows(4, std::vector<unsigned char>(8, 100));
  const std::vector<unsigned char> good = encodePng(rows, 8, 8, 0, 1, 1, 1);
  cv::Mat out;
  ASSERT_TRUE(decodePngFast(good.data(), good.size(), &out));

  std::vector<unsigned char> bad_crc = good;
  bad_crc[8 + 8 + 2] ^= 1;  // a byte of IHDR's width
  EXPECT_FALSE(decodePngFast(bad_crc.data(), bad_crc.size(), &out));
  const std::vector<unsigned char> truncated(good.begin(), good.end() - 20);
  EXPECT_FALSE(decodePngFast(truncated.data(), truncated.size(), &out));
  // IHDR edited with a valid CRC: interlaced (Adam7) is cv::imread's business; 60000 x 8000
  // pixels over 20 bytes of data cannot be true (deflate expands at most 1032-fold) and must be
  // declined before 480 MB are allocated for them.
  auto editedHeader = [&](int offset, const std::vector<unsigned char>& bytes) {
    std::vector<unsigned char> png = good;
    std::copy(bytes.begin(), bytes.end(), png.begin() + 16 + offset);
    const uint32_t crc = libdeflate_crc32(0, &png[12], 4 + 13);
    for (int k = 0; k < 4; ++k) png[29 + k] = static_cast<unsigned char>(crc >> (24 - 8 * k));
    return png;
  };
  const std::vector<unsigned char> interlaced = editedHeader(12, {1});
  EXPECT_FALSE(decodePngFast(interlaced.data(), interlaced.size(), &out));
  const std::vector<unsigned char> huge = editedHeader(0, {0, 0, 0xea, 0x60, 0, 0, 0x1f, 0x40});
  const long peak_before_kb = peakRssKb();
  EXPECT_FALSE(decodePngFast(huge.data(), huge.size(), &out));
  EXPECT_LT(peakRssKb() - peak_before_kb, 100 * 1024);
  const std::vector<unsigned char> unchanged = editedHeader(12, {0});
  EXPECT_TRUE(decodePngFast(unchanged.data(), unchanged.size(), &out));
  const std::vector<unsigned char> palette = encodePng(rows, 8, 8, 3, 1, 1, 1);
  EXPECT_FALSE(decodePngFast(palette.data(), palette.size(), &out));

  // Through readImageUnchanged: cv::imread's answers (empty for damaged data).
  EXPECT_TRUE(readImageUnchanged(write("crc.png", bad_crc)).empty());
  EXPECT_TRUE(readImageUnchanged(write("truncated.png", truncated)).empty());
  EXPECT_TRUE(readImageUnchanged((dir_ / "missing.png").string()).empty());
  cv::Mat jpeg_source(16, 16, CV_8UC3, cv::Scalar(10, 20, 30));
  const std::string jpeg = (dir_ / "image.jpg").string();
  ASSERT_TRUE(cv::imwrite(jpeg, jpeg_source));
  EXPECT_EQ(readImageUnchanged(jpeg).type(), CV_8UC3);
}

}  // namespace
}  // namespace ltlo::io
