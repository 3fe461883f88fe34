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

// One pass over a PLY file: the header's elements, then each element's values in turn.
class PlyReader {
 public:
  explicit PlyReader(const std::string& path) : path_(path), in_(path, std::ios::binary) {
    if (!in_) throw InputError(path, 0, "cannot open mesh");
  }

  // Fills elements_ and binary_ from the header, up to and including end_header.
  void readHeader() {
    if (headerLine() != "ply") throw InputError(path_, 1, "not a PLY file");
    for (;;) {
      std::istringstream is(headerLine());
      std::string word;
      is >> word;
      if (word == "end_header") break;
      if (word == "comment" || word == "obj_info" || word.empty()) continue;
      if (word == "format") {
        readFormat(is);
      } else if (word == "element") {
        Element element;
        if (!(is >> element.name >> element.count) || element.count < 0) {
          throw InputError(path_, line_number_, "bad element line \"" + line_ + "\"");
        }
        elements_.push_back(element);
      } else if (word == "property") {
        readProperty(is);
      } else {
        throw InputError(path_, line_number_, "unexpected header line \"" + line_ + "\"");
      }
    }
  }

  // The vertices and faces (fans split into triangles) of the body; other elements are skipped.
  TriangleMesh readBody() {
    TriangleMesh mesh;
    for (const Element& element : elements_) readElement(element, &mesh);
    return mesh;
  }

 private:
  std::string headerLine() {
    if (!std::getline(in_, line_))
      throw InputError(path_, line_number_, "header ends before end_header");
    ++line_number_;
    while (!line_.empty() && line_.back() == '\r') line_.pop_back();
    return line_;
  }

  void readFormat(std::istringstream& is) {
    std::string format;
    is >> format;
    if (format == "binary_little_endian") {
      binary_ = true;
    } else if (format != "ascii") {
      throw InputError(path_, line_number_, "unsupported format " + format);
    }
  }

  void readProperty(std::istringstream& is) {
    if (elements_.empty()) throw InputError(path_, line_number_, "property before any element");
    Property property;
    std::string type;
    is >> type;
    if (type == "list") {
      is >> property.list_count >> property.type >> property.name;
      if (typeBytes(property.list_count) == 0 || typeBytes(property.type) == 0) {
        throw InputError(path_, line_number_, "bad list property \"" + line_ + "\"");
      }
    } else {
      property.type = type;
      is >> property.name;
      if (typeBytes(type) == 0) throw InputError(path_, line_number_, "unknown type " + type);
    }
    elements_.back().properties.push_back(property);
  }

  void readElement(const Element& element, TriangleMesh* mesh) {
    int ix = -1, iy = -1, iz = -1;
    for (int p = 0; p < static_cast<int>(element.properties.size()); ++p) {
      const std::string& name = element.properties[p].name;
      if (name == "x") ix = p;
      if (name == "y") iy = p;
      if (name == "z") iz = p;
    }
    if (element.name == "vertex" && (ix < 0 || iy < 0 || iz < 0)) {
      throw InputError(path_, 0, "vertex element without x, y, z");
    }
    std::vector<double> values;
    std::vector<long> indices;
    for (long e = 0; e < element.count; ++e) {
      values.clear();
      indices.clear();
      readValues(element, e, &values, &indices);
      if (element.name == "vertex") {
        mesh->vertices.emplace_back(static_cast<float>(values[ix]), static_cast<float>(values[iy]),
                                    static_cast<float>(values[iz]));
      } else if (element.name == "face") {
        for (std::size_t k = 2; k < indices.size(); ++k) {
          mesh->triangles.push_back({static_cast<int>(indices[0]), static_cast<int>(indices[k - 1]),
                                     static_cast<int>(indices[k])});
        }
      }
    }
  }

  // Item `e` of `element`: one value per scalar property (0 for a list), the list entries in indices.
  void readValues(const Element& element, long e, std::vector<double>* values,
                  std::vector<long>* indices) {
    std::istringstream ascii_line;
    if (!binary_) {
      if (!std::getline(in_, line_)) {
        throw InputError(path_, line_number_,
                         "truncated: " + element.name + " " + std::to_string(e) + " of " +
                             std::to_string(element.count));
      }
      ++line_number_;
      ascii_line.str(line_);
    }
    for (const Property& property : element.properties) {
      auto read_value = [&](const std::string& type) {
        if (binary_) return readBinary(in_, type, path_);
        double v = 0.0;
        if (!(ascii_line >> v)) {
          throw InputError(path_, line_number_, "missing value for " + property.name);
        }
        return v;
      };
      if (property.list_count.empty()) {
        values->push_back(read_value(property.type));
      } else {
        const long n = static_cast<long>(read_value(property.list_count));
        values->push_back(0.0);
        for (long k = 0; k < n; ++k)
          indices->push_back(static_cast<long>(read_value(property.type)));
      }
    }
  }

  const std::string& path_;
  std::ifstream in_;
  std::string line_;
  int line_number_ = 0;
  bool binary_ = false;
  std::vector<Element> elements_;
};

void checkFaceIndices(const TriangleMesh& mesh, const std::string& path) {
  for (const std::array<int, 3>& t : mesh.triangles) {
    for (int index : t) {
      if (index < 0 || index >= static_cast<int>(mesh.vertices.size())) {
        throw InputError(path, 0,
                         "face index " + std::to_string(index) + " out of range (" +
                             std::to_string(mesh.vertices.size()) + " vertices)");
      }
    }
  }
}

}  // namespace

TriangleMesh readPlyMesh(const std::string& path) {
  PlyReader reader(path);
  reader.readHeader();
  TriangleMesh mesh = reader.readBody();
  checkFaceIndices(mesh, path);
  if (mesh.triangles.empty()) throw InputError(path, 0, "mesh has no faces");
  return mesh;
}

}  // namespace ltlo::eval
