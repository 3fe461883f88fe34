#pragma once
/// Little-endian byte writing and bounded reading for the atlas file (atlas_file.h), CRC32 and
/// FNV-1a 64. Public: the stages above the map write and read their parts of the atlas file's run
/// state with it (run_state_io.h).
///
/// The reader is a cursor over one section of a file held in memory: it knows the file's name,
/// the section's name and its offset in the file, and throws AtlasFileError naming all three and
/// the absolute byte offset of the field at fault. Nothing is allocated from a count before the
/// count was checked against the bytes left (readCount).
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"

namespace ltlo::map {

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320), table-driven; `crc` continues a running
/// value (0 to start).
std::uint32_t crc32(const char* data, std::size_t size, std::uint32_t crc = 0);
/// FNV-1a 64 of the bytes.
std::uint64_t fnv1a64(const char* data, std::size_t size);
inline std::uint64_t fnv1a64(const std::string& text) { return fnv1a64(text.data(), text.size()); }
/// A double with 17 significant digits (every bit shows): error values and the settings summary.
std::string exactNumberText(double v);

/// Appends little-endian values to a byte string.
class ByteWriter {
 public:
  void u8(std::uint8_t v) { bytes_.push_back(static_cast<char>(v)); }
  void u16(std::uint16_t v) { put(v); }
  void u32(std::uint32_t v) { put(v); }
  void u64(std::uint64_t v) { put(v); }
  void i32(std::int32_t v) { put(static_cast<std::uint32_t>(v)); }
  void f32(float v) { put(bitsOf<std::uint32_t>(v)); }
  void f64(double v) { put(bitsOf<std::uint64_t>(v)); }
  void boolean(bool v) { u8(v ? 1 : 0); }
  void vec3(const Vec3& v);
  void mat3(const Mat3& m);  ///< row-major
  /// Quaternion (x y z w) then translation, the exact doubles Sophus holds.
  void se3(const SE3& T);
  void text(const std::string& s);  ///< u64 length + bytes
  void raw(const void* data, std::size_t size) { bytes_.append(static_cast<const char*>(data), size); }

  std::size_t size() const { return bytes_.size(); }
  const std::string& bytes() const { return bytes_; }
  std::string& bytes() { return bytes_; }

 private:
  template <typename To, typename From>
  static To bitsOf(From v) {
    static_assert(sizeof(To) == sizeof(From), "bit copy of equal sizes");
    To bits;
    std::memcpy(&bits, &v, sizeof(bits));
    return bits;
  }
  template <typename T>
  void put(T v) {
    static_assert(std::is_unsigned<T>::value, "unsigned only");
    for (std::size_t k = 0; k < sizeof(T); ++k) bytes_.push_back(static_cast<char>((v >> (8 * k)) & 0xFF));
  }
  std::string bytes_;
};

/// Bounded little-endian reader over [data, data + size) of a section starting at byte
/// `file_offset` of `file`. Every read past the end throws AtlasFileError ("truncated").
class ByteReader {
 public:
  ByteReader(const char* data, std::size_t size, std::string file, std::string section, std::uint64_t file_offset);

  std::uint8_t u8(const char* what);
  std::uint16_t u16(const char* what) { return static_cast<std::uint16_t>(get(2, what)); }
  std::uint32_t u32(const char* what) { return static_cast<std::uint32_t>(get(4, what)); }
  std::uint64_t u64(const char* what) { return get(8, what); }
  std::int32_t i32(const char* what) { return static_cast<std::int32_t>(u32(what)); }
  bool boolean(const char* what);
  /// Any float/double bit pattern, finite or not (for fields where the caller checks).
  float f32(const char* what);
  double f64(const char* what);
  /// Finite values only, else AtlasFileError naming the field and value.
  float finiteF32(const char* what);
  double finiteF64(const char* what);
  /// A finite double in [min, max].
  double f64InRange(const char* what, double min, double max);
  /// An i32 in [min, max].
  std::int32_t i32InRange(const char* what, std::int32_t min, std::int32_t max);
  Vec3 vec3(const char* what);
  Mat3 mat3(const char* what);
  /// A unit quaternion (|q| within 1e-6 of 1) and a finite translation.
  SE3 se3(const char* what);
  std::string text(const char* what, std::size_t max_length = 1u << 20);
  void raw(void* out, std::size_t size, const char* what);
  /// A count of items of at least `min_item_bytes` each: refused when they cannot fit in the bytes
  /// left (so no allocation follows from an absurd count).
  std::size_t count(const char* what, std::size_t min_item_bytes);

  std::size_t remaining() const { return size_ - position_; }
  /// Absolute byte offset in the file of the next field.
  std::uint64_t fileOffset() const { return file_offset_ + position_; }
  /// Throws AtlasFileError at the current field (or at `offset`).
  [[noreturn]] void fail(const std::string& what, const std::string& value) const;
  [[noreturn]] void failAt(std::uint64_t offset, const std::string& what, const std::string& value) const;
  /// Bytes left over after the last field are an error (a writer of another layout).
  void expectEnd();

 private:
  std::uint64_t get(std::size_t bytes, const char* what);
  void need(std::size_t bytes, const char* what) const;

  const char* data_;
  std::size_t size_;
  std::size_t position_ = 0;
  std::string file_;
  std::string section_;
  std::uint64_t file_offset_;
};

}  // namespace ltlo::map
