// readPlyMesh: the vertex positions and faces of a PLY file (ascii or binary_little_endian).
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "ltlo/core/errors.h"
#include "ltlo/eval/surfel_check.h"

namespace ltlo::eval {
namespace {

struct Property {
  std::string name;
  std::string type;        // scalar type, or the index type of a list
  std::string list_count;  // count type of a list, empty for scalars
};

struct Element {
  std::string name;
  long count = 0;
  std::vector<Property> properties;
};

int typeBytes(const std::string& type) {
  if (type == "char" || type == "uchar" || type == "int8" || type == "uint8") return 1;
  if (type == "short" || type == "ushort" || type == "int16" || type == "uint16") return 2;
  if (type == "int" || type == "uint" || type == "float" || type == "int32" || type == "uint32" ||
      type == "float32") {
    return 4;
  }
  if (type == "double" || type == "float64") return 8;
  return 0;
}

// Reads one binary little-endian value of `type` as a double.
double readBinary(std::istream& in, const std::string& type, const std::string& path) {
  unsigned char bytes[8] = {};
  const int n = typeBytes(type);
  if (!in.read(reinterpret_cast<char*>(bytes), n)) throw InputError(path, 0, "truncated data");
  uint64_t bits = 0;
  for (int b = 0; b < n; ++b) bits |= static_cast<uint64_t>(bytes[b]) << (8 * b);
  if (type == "float" || type == "float32") {
    const uint32_t b32 = static_cast<uint32_t>(bits);
    float f = 0.0f;
    std::memcpy(&f, &b32, 4);
    return f;
  }
  if (type == "double" || type == "float64") {
    double d = 0.0;
    std::memcpy(&d, &bits, 8);
    return d;
  }
  const bool is_signed = type == "char" || type == "short" || type == "int" || type == "int8" ||
                         type == "int16" || type == "int32";
  if (is_signed && n < 8 && (bits >> (8 * n - 1)) & 1) bits |= ~uint64_t{0} << (8 * n);
  return is_signed ? static_cast<double>(static_cast<int64_t>(bits)) : static_cast<double>(bits);
}

}  // namespace

TriangleMesh readPlyMesh(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot open mesh");
  std::string line;
  int line_number = 0;
  auto header_line = [&]() {
    if (!std::getline(in, line))
      throw InputError(path, line_number, "header ends before end_header");
    ++line_number;
    while (!line.empty() && line.back() == '\r') line.pop_back();
    return line;
  };
  if (header_line() != "ply") throw InputError(path, 1, "not a PLY file");
  bool binary = false;
  std::vector<Element> elements;
  for (;;) {
    std::istringstream is(header_line());
    std::string word;
    is >> word;
    if (word == "end_header") break;
    if (word == "comment" || word == "obj_info" || word.empty()) continue;
    if (word == "format") {
      std::string format;
      is >> format;
      if (format == "binary_little_endian") {
        binary = true;
      } else if (format != "ascii") {
        throw InputError(path, line_number, "unsupported format " + format);
      }
    } else if (word == "element") {
      Element element;
      if (!(is >> element.name >> element.count) || element.count < 0) {
        throw InputError(path, line_number, "bad element line \"" + line + "\"");
      }
      elements.push_back(element);
    } else if (word == "property") {
      if (elements.empty()) throw InputError(path, line_number, "property before any element");
      Property property;
      std::string type;
      is >> type;
      if (type == "list") {
        is >> property.list_count >> property.type >> property.name;
        if (typeBytes(property.list_count) == 0 || typeBytes(property.type) == 0) {
          throw InputError(path, line_number, "bad list property \"" + line + "\"");
        }
      } else {
        property.type = type;
        is >> property.name;
        if (typeBytes(type) == 0) throw InputError(path, line_number, "unknown type " + type);
      }
      elements.back().properties.push_back(property);
    } else {
      throw InputError(path, line_number, "unexpected header line \"" + line + "\"");
    }
  }

  TriangleMesh mesh;
  for (const Element& element : elements) {
    int ix = -1, iy = -1, iz = -1;
    for (int p = 0; p < static_cast<int>(element.properties.size()); ++p) {
      const std::string& name = element.properties[p].name;
      if (name == "x") ix = p;
      if (name == "y") iy = p;
      if (name == "z") iz = p;
    }
    if (element.name == "vertex" && (ix < 0 || iy < 0 || iz < 0)) {
      throw InputError(path, 0, "vertex element without x, y, z");
    }
    std::vector<double> values;
    std::vector<long> indices;
    for (long e = 0; e < element.count; ++e) {
      values.clear();
      indices.clear();
      std::istringstream ascii_line;
      if (!binary) {
        if (!std::getline(in, line)) {
          throw InputError(path, line_number,
                           "truncated: " + element.name + " " + std::to_string(e) + " of " +
                               std::to_string(element.count));
        }
        ++line_number;
        ascii_line.str(line);
      }
      for (const Property& property : element.properties) {
        auto read_value = [&](const std::string& type) {
          if (binary) return readBinary(in, type, path);
          double v = 0.0;
          if (!(ascii_line >> v)) {
            throw InputError(path, line_number, "missing value for " + property.name);
          }
          return v;
        };
        if (property.list_count.empty()) {
          values.push_back(read_value(property.type));
        } else {
          const long n = static_cast<long>(read_value(property.list_count));
          values.push_back(0.0);
          for (long k = 0; k < n; ++k)
            indices.push_back(static_cast<long>(read_value(property.type)));
        }
      }
      if (element.name == "vertex") {
        mesh.vertices.emplace_back(static_cast<float>(values[ix]), static_cast<float>(values[iy]),
                                   static_cast<float>(values[iz]));
      } else if (element.name == "face") {
        for (std::size_t k = 2; k < indices.size(); ++k) {
          mesh.triangles.push_back({static_cast<int>(indices[0]), static_cast<int>(indices[k - 1]),
                                    static_cast<int>(indices[k])});
        }
      }
    }
  }
  for (const std::array<int, 3>& t : mesh.triangles) {
    for (int index : t) {
      if (index < 0 || index >= static_cast<int>(mesh.vertices.size())) {
        throw InputError(path, 0,
                         "face index " + std::to_string(index) + " out of range (" +
                             std::to_string(mesh.vertices.size()) + " vertices)");
      }
    }
  }
  if (mesh.triangles.empty()) throw InputError(path, 0, "mesh has no faces");
  return mesh;
}

}  // namespace ltlo::eval
