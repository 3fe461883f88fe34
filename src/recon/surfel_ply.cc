#include "ltlo/recon/surfel_ply.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>

#include "ltlo/core/errors.h"

namespace ltlo::recon {
namespace {

constexpr const char* kProperties[] = {
    "property float x",      "property float y",         "property float z",
    "property float nx",     "property float ny",        "property float nz",
    "property uchar red",    "property uchar green",     "property uchar blue",
    "property float radius", "property float confidence"};
constexpr std::size_t kRecordBytes = 6 * 4 + 3 + 2 * 4;

// Little-endian byte order whatever the host's.
void putFloat(float value, char* out) {
  uint32_t bits = 0;
  std::memcpy(&bits, &value, 4);
  for (int b = 0; b < 4; ++b) out[b] = static_cast<char>((bits >> (8 * b)) & 0xff);
}

float getFloat(const char* in) {
  uint32_t bits = 0;
  for (int b = 0; b < 4; ++b) bits |= static_cast<uint32_t>(static_cast<uint8_t>(in[b])) << (8 * b);
  float value = 0.0f;
  std::memcpy(&value, &bits, 4);
  return value;
}

uint8_t toByte(float value) {
  return static_cast<uint8_t>(std::lround(std::min(255.0f, std::max(0.0f, value))));
}

}  // namespace

void writeSurfelPly(const std::string& path, const std::vector<Surfel>& surfels) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  out << "ply\nformat binary_little_endian 1.0\n"
      << "comment LTLO-SLAM surfels of the static background (world frame of the trajectory, m)\n"
      << "element vertex " << surfels.size() << "\n";
  for (const char* property : kProperties) out << property << "\n";
  out << "end_header\n";
  std::vector<char> buffer(kRecordBytes * std::min<std::size_t>(surfels.size(), 65536));
  std::size_t in_buffer = 0;
  for (const Surfel& s : surfels) {
    char* r = buffer.data() + kRecordBytes * in_buffer;
    for (int a = 0; a < 3; ++a) putFloat(s.position_w[a], r + 4 * a);
    for (int a = 0; a < 3; ++a) putFloat(s.normal_w[a], r + 12 + 4 * a);
    for (int a = 0; a < 3; ++a) r[24 + a] = static_cast<char>(toByte(s.colour_rgb[a]));
    putFloat(s.radius_m, r + 27);
    putFloat(s.confidence, r + 31);
    if (++in_buffer * kRecordBytes == buffer.size()) {
      out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      in_buffer = 0;
    }
  }
  out.write(buffer.data(), static_cast<std::streamsize>(in_buffer * kRecordBytes));
  if (!out) throw InputError(path, 0, "write failed");
}

std::vector<Surfel> readSurfelPly(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot open surfel PLY");
  std::string line;
  int line_number = 0;
  auto nextLine = [&](const char* what) {
    if (!std::getline(in, line))
      throw InputError(path, line_number, std::string("missing ") + what);
    ++line_number;
    while (!line.empty() && line.back() == '\r') line.pop_back();
  };
  nextLine("\"ply\"");
  if (line != "ply") throw InputError(path, line_number, "not a PLY file (\"" + line + "\")");
  nextLine("format line");
  if (line != "format binary_little_endian 1.0") {
    throw InputError(path, line_number,
                     "expected binary_little_endian 1.0, found \"" + line + "\"");
  }
  long count = -1;
  std::size_t property = 0;
  for (;;) {
    nextLine("end_header");
    if (line == "end_header") break;
    if (line.rfind("comment", 0) == 0) continue;
    if (line.rfind("element vertex ", 0) == 0) {
      const std::string count_text = line.substr(15);
      char* end = nullptr;
      errno = 0;
      const long long parsed = std::strtoll(count_text.c_str(), &end, 10);
      if (count >= 0 || count_text.empty() || *end != '\0' || errno == ERANGE || parsed < 0) {
        throw InputError(path, line_number, "bad or repeated vertex count '" + count_text + "'");
      }
      count = static_cast<long>(parsed);
      continue;
    }
    if (property >= std::size(kProperties) || line != kProperties[property]) {
      throw InputError(
          path, line_number,
          "unexpected header line \"" + line + "\" (expected \"" +
              (property < std::size(kProperties) ? kProperties[property] : "end_header") + "\")");
    }
    ++property;
  }
  if (count < 0) throw InputError(path, line_number, "no \"element vertex\" line");
  if (property != std::size(kProperties)) {
    throw InputError(path, line_number,
                     "header lists " + std::to_string(property) + " of " +
                         std::to_string(std::size(kProperties)) + " properties");
  }
  // The announced count must fit in the file before anything is allocated for it (a corrupt count
  // would otherwise ask for terabytes).
  const std::streamoff body_begin = in.tellg();
  in.seekg(0, std::ios::end);
  const std::streamoff body_bytes = in.tellg() - body_begin;
  in.seekg(body_begin);
  if (body_begin < 0 || !in ||
      body_bytes / static_cast<std::streamoff>(kRecordBytes) < static_cast<std::streamoff>(count)) {
    throw InputError(path, 0,
                     "truncated: " + std::to_string(std::max<std::streamoff>(body_bytes, 0) /
                                                    static_cast<std::streamoff>(kRecordBytes)) +
                         " of " + std::to_string(count) + " surfels");
  }
  std::vector<Surfel> surfels(static_cast<std::size_t>(count));
  std::vector<char> record(kRecordBytes);
  for (long i = 0; i < count; ++i) {
    if (!in.read(record.data(), kRecordBytes)) {
      throw InputError(
          path, 0, "truncated: " + std::to_string(i) + " of " + std::to_string(count) + " surfels");
    }
    Surfel& s = surfels[static_cast<std::size_t>(i)];
    const char* r = record.data();
    for (int a = 0; a < 3; ++a) s.position_w[a] = getFloat(r + 4 * a);
    for (int a = 0; a < 3; ++a) s.normal_w[a] = getFloat(r + 12 + 4 * a);
    for (int a = 0; a < 3; ++a) s.colour_rgb[a] = static_cast<uint8_t>(r[24 + a]);
    s.radius_m = getFloat(r + 27);
    s.confidence = getFloat(r + 31);
    if (!s.position_w.allFinite() || !s.normal_w.allFinite() || !std::isfinite(s.radius_m) ||
        !std::isfinite(s.confidence)) {
      throw InputError(path, 0, "surfel " + std::to_string(i) + " has a value that is not finite");
    }
  }
  return surfels;
}

}  // namespace ltlo::recon
