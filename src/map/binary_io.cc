#include "ltlo/map/binary_io.h"

#include <array>
#include <cmath>
#include <sstream>

#include "ltlo/map/atlas_file.h"

namespace ltlo::map {

namespace {

std::array<std::uint32_t, 256> makeCrcTable() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t n = 0; n < 256; ++n) {
    std::uint32_t c = n;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[n] = c;
  }
  return table;
}

}  // namespace

std::uint32_t crc32(const char* data, std::size_t size, std::uint32_t crc) {
  static const std::array<std::uint32_t, 256> table = makeCrcTable();
  crc = ~crc;
  for (std::size_t i = 0; i < size; ++i) {
    crc = table[(crc ^ static_cast<std::uint8_t>(data[i])) & 0xFFu] ^ (crc >> 8);
  }
  return ~crc;
}

std::uint64_t fnv1a64(const char* data, std::size_t size) {
  std::uint64_t hash = 14695981039346656037ULL;
  for (std::size_t i = 0; i < size; ++i) {
    hash ^= static_cast<std::uint8_t>(data[i]);
    hash *= 1099511628211ULL;
  }
  return hash;
}

void ByteWriter::vec3(const Vec3& v) {
  for (int k = 0; k < 3; ++k) f64(v[k]);
}

void ByteWriter::mat3(const Mat3& m) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) f64(m(r, c));
  }
}

void ByteWriter::se3(const SE3& T) {
  const Quat& q = T.quaternion();
  f64(q.x());
  f64(q.y());
  f64(q.z());
  f64(q.w());
  vec3(T.translation());
}

void ByteWriter::text(const std::string& s) {
  u64(s.size());
  raw(s.data(), s.size());
}

ByteReader::ByteReader(const char* data, std::size_t size, std::string file, std::string section,
                       std::uint64_t file_offset)
    : data_(data), size_(size), file_(std::move(file)), section_(std::move(section)), file_offset_(file_offset) {}

void ByteReader::fail(const std::string& what, const std::string& value) const { failAt(fileOffset(), what, value); }

void ByteReader::failAt(std::uint64_t offset, const std::string& what, const std::string& value) const {
  throw AtlasFileError(file_, section_, offset, what, value);
}

void ByteReader::need(std::size_t bytes, const char* what) const {
  if (bytes > remaining()) {
    fail(std::string("truncated: ") + what + " needs " + std::to_string(bytes) + " bytes",
         std::to_string(remaining()) + " left");
  }
}

std::uint64_t ByteReader::get(std::size_t bytes, const char* what) {
  need(bytes, what);
  std::uint64_t v = 0;
  for (std::size_t k = 0; k < bytes; ++k) {
    v |= static_cast<std::uint64_t>(static_cast<std::uint8_t>(data_[position_ + k])) << (8 * k);
  }
  position_ += bytes;
  return v;
}

std::uint8_t ByteReader::u8(const char* what) { return static_cast<std::uint8_t>(get(1, what)); }

bool ByteReader::boolean(const char* what) {
  const std::uint64_t offset = fileOffset();
  const std::uint8_t v = u8(what);
  if (v > 1) failAt(offset, std::string(what) + " is not a flag (0 or 1)", std::to_string(v));
  return v == 1;
}

float ByteReader::f32(const char* what) {
  const std::uint32_t bits = u32(what);
  float v;
  std::memcpy(&v, &bits, sizeof(v));
  return v;
}

double ByteReader::f64(const char* what) {
  const std::uint64_t bits = u64(what);
  double v;
  std::memcpy(&v, &bits, sizeof(v));
  return v;
}

float ByteReader::finiteF32(const char* what) {
  const std::uint64_t offset = fileOffset();
  const float v = f32(what);
  if (!std::isfinite(v)) failAt(offset, std::string(what) + " is not finite", exactNumberText(v));
  return v;
}

double ByteReader::finiteF64(const char* what) {
  const std::uint64_t offset = fileOffset();
  const double v = f64(what);
  if (!std::isfinite(v)) failAt(offset, std::string(what) + " is not finite", exactNumberText(v));
  return v;
}

double ByteReader::f64InRange(const char* what, double min, double max) {
  const std::uint64_t offset = fileOffset();
  const double v = finiteF64(what);
  if (v < min || v > max) {
    failAt(offset, std::string(what) + " out of [" + exactNumberText(min) + ", " + exactNumberText(max) + "]",
           exactNumberText(v));
  }
  return v;
}

std::int32_t ByteReader::i32InRange(const char* what, std::int32_t min, std::int32_t max) {
  const std::uint64_t offset = fileOffset();
  const std::int32_t v = i32(what);
  if (v < min || v > max) {
    failAt(offset, std::string(what) + " out of [" + std::to_string(min) + ", " + std::to_string(max) + "]",
           std::to_string(v));
  }
  return v;
}

Vec3 ByteReader::vec3(const char* what) {
  Vec3 v;
  for (int k = 0; k < 3; ++k) v[k] = finiteF64(what);
  return v;
}

Mat3 ByteReader::mat3(const char* what) {
  Mat3 m;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m(r, c) = finiteF64(what);
  }
  return m;
}

SE3 ByteReader::se3(const char* what) {
  const std::uint64_t offset = fileOffset();
  const double x = finiteF64(what), y = finiteF64(what), z = finiteF64(what), w = finiteF64(what);
  const Quat q(w, x, y, z);
  if (std::abs(q.norm() - 1.0) > 1e-6) {
    failAt(offset, std::string(what) + ": rotation is not a unit quaternion", "|q| = " + exactNumberText(q.norm()));
  }
  const Vec3 t = vec3(what);
  return SE3::fromUnitQuaternion(q, t);
}

std::string ByteReader::text(const char* what, std::size_t max_length) {
  const std::uint64_t offset = fileOffset();
  const std::uint64_t length = u64(what);
  if (length > max_length || length > remaining()) {
    failAt(offset, std::string(what) + ": length exceeds the bytes left", std::to_string(length));
  }
  std::string s(data_ + position_, static_cast<std::size_t>(length));
  position_ += static_cast<std::size_t>(length);
  return s;
}

void ByteReader::raw(void* out, std::size_t size, const char* what) {
  need(size, what);
  std::memcpy(out, data_ + position_, size);
  position_ += size;
}

std::size_t ByteReader::count(const char* what, std::size_t min_item_bytes) {
  const std::uint64_t offset = fileOffset();
  const std::uint64_t n = u64(what);
  const std::uint64_t item = min_item_bytes == 0 ? 1 : min_item_bytes;
  if (n > remaining() / item) {
    failAt(offset, std::string(what) + " count exceeds the bytes left (" + std::to_string(remaining()) + ")",
           std::to_string(n));
  }
  return static_cast<std::size_t>(n);
}

void ByteReader::expectEnd() {
  if (remaining() != 0) fail("bytes left after the last field", std::to_string(remaining()));
}

std::string exactNumberText(double v) {
  std::ostringstream os;
  os.precision(17);
  os << v;
  return os.str();
}

}  // namespace ltlo::map
