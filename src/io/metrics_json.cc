#include "ltlo/io/metrics_json.h"

#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "ltlo/core/errors.h"
#include "text_parse.h"

namespace ltlo::io {
namespace {

std::string jsonEscape(const std::string& text) {
  std::ostringstream os;
  for (const char c : text) {
    switch (c) {
      case '"':
        os << "\\\"";
        break;
      case '\\':
        os << "\\\\";
        break;
      case '\n':
        os << "\\n";
        break;
      case '\t':
        os << "\\t";
        break;
      case '\r':
        os << "\\r";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          os << "\\u" << std::hex << std::setw(4) << std::setfill('0') << static_cast<int>(c)
             << std::dec << std::setfill(' ');
        } else {
          os << c;
        }
    }
  }
  return os.str();
}

std::string doubleText(double value, int digits) {
  std::ostringstream os;
  os << std::setprecision(digits) << value;
  return os.str();
}

}  // namespace

void Metrics::setValue(const std::string& name, Value value) {
  for (auto& entry : entries_) {
    if (entry.first == name) {
      entry.second = std::move(value);
      return;
    }
  }
  entries_.emplace_back(name, std::move(value));
}

void Metrics::set(const std::string& name, double value) { setValue(name, value); }
void Metrics::set(const std::string& name, int64_t value) { setValue(name, value); }
void Metrics::set(const std::string& name, const std::string& value) { setValue(name, value); }
void Metrics::setFlag(const std::string& name, bool value) { setValue(name, value); }

bool Metrics::has(const std::string& name) const {
  for (const auto& entry : entries_) {
    if (entry.first == name) return true;
  }
  return false;
}

double Metrics::number(const std::string& name) const {
  for (const auto& entry : entries_) {
    if (entry.first != name) continue;
    if (const double* d = std::get_if<double>(&entry.second)) return *d;
    if (const int64_t* i = std::get_if<int64_t>(&entry.second)) return static_cast<double>(*i);
    if (const bool* flag = std::get_if<bool>(&entry.second)) return *flag ? 1.0 : 0.0;
    throw std::out_of_range("metric '" + name + "' is not a number");
  }
  throw std::out_of_range("no metric '" + name + "'");
}

std::string Metrics::toText() const {
  std::ostringstream os;
  for (const auto& [name, value] : entries_) {
    os << name << ' ';
    if (const double* d = std::get_if<double>(&value)) {
      os << doubleText(*d, 9);
    } else if (const int64_t* i = std::get_if<int64_t>(&value)) {
      os << *i;
    } else if (const bool* flag = std::get_if<bool>(&value)) {
      os << (*flag ? "true" : "false");
    } else {
      os << std::get<std::string>(value);
    }
    os << '\n';
  }
  return os.str();
}

std::string Metrics::toJson() const {
  std::ostringstream os;
  os << "{";
  bool first = true;
  for (const auto& [name, value] : entries_) {
    os << (first ? "\n" : ",\n") << "  \"" << jsonEscape(name) << "\": ";
    first = false;
    if (const double* d = std::get_if<double>(&value)) {
      os << (std::isfinite(*d) ? doubleText(*d, 17) : "null");
    } else if (const int64_t* i = std::get_if<int64_t>(&value)) {
      os << *i;
    } else if (const bool* flag = std::get_if<bool>(&value)) {
      os << (*flag ? "true" : "false");
    } else {
      os << '"' << jsonEscape(std::get<std::string>(value)) << '"';
    }
  }
  os << "\n}\n";
  return os.str();
}

void Metrics::writeJson(const std::string& path) const {
  const std::string json = toJson();
  detail::writeAtomically(path, [&](std::ostream& out) { out << json; });
}

}  // namespace ltlo::io
