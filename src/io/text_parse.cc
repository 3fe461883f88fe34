#include "text_parse.h"

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <sstream>

#include "ltlo/core/errors.h"

namespace ltlo::io::detail {

bool LineReader::next() {
  if (!std::getline(in_, line_)) return false;
  ++number_;
  if (!line_.empty() && line_.back() == '\r') line_.pop_back();
  if (number_ == 1 && line_.rfind("\xEF\xBB\xBF", 0) == 0) line_.erase(0, 3);
  return true;
}

bool isCommentOrBlank(const std::string& line) {
  const size_t first = line.find_first_not_of(" \t\r");
  return first == std::string::npos || line[first] == '#';
}

std::vector<std::string> splitFields(const std::string& line, char separator) {
  std::vector<std::string> fields;
  std::string current;
  for (const char c : line) {
    if (c == separator || c == ' ' || c == '\t' || c == '\r' || c == '\n') {
      if (!current.empty()) fields.push_back(current);
      current.clear();
    } else {
      current.push_back(c);
    }
  }
  if (!current.empty()) fields.push_back(current);
  return fields;
}

double parseFinite(const std::string& token, const std::string& what, const std::string& path,
                   int line_number) {
  char* end = nullptr;
  const double value = std::strtod(token.c_str(), &end);
  if (token.empty() || end == token.c_str() || *end != '\0') {
    throw InputError(path, line_number, what + " is not a number: '" + token + "'");
  }
  if (!std::isfinite(value)) {
    throw InputError(path, line_number, what + " is not finite: '" + token + "'");
  }
  return value;
}

std::vector<double> parseNumbers(const std::string& line, char separator, size_t count,
                                 bool allow_extra, const std::string& path, int line_number) {
  const std::vector<std::string> fields = splitFields(line, separator);
  if (fields.size() < count || (!allow_extra && fields.size() > count)) {
    throw InputError(path, line_number,
                     "expected " + std::to_string(count) + " values, found " +
                         std::to_string(fields.size()) + " in '" + line + "'");
  }
  std::vector<double> values;
  values.reserve(count);
  for (size_t i = 0; i < count; ++i) {
    values.push_back(parseFinite(fields[i], "value " + std::to_string(i + 1), path, line_number));
  }
  return values;
}

double parseNanosecondsAsSeconds(const std::string& token, const std::string& path,
                                 int line_number) {
  char* end = nullptr;
  errno = 0;
  const long long ns = std::strtoll(token.c_str(), &end, 10);
  if (token.empty() || end == token.c_str() || *end != '\0' || errno == ERANGE || ns < 0) {
    throw InputError(path, line_number,
                     "timestamp is not a non-negative integer of nanoseconds: '" + token + "'");
  }
  // Whole seconds and the nanosecond remainder separately: both are exact in a double, so the
  // sum is the double nearest to the true time (ns * 1e-9 would round twice).
  const long long kNsPerS = 1000000000LL;
  return static_cast<double>(ns / kNsPerS) + static_cast<double>(ns % kNsPerS) * 1e-9;
}

std::string joinPath(const std::string& dir, const std::string& name) {
  if (dir.empty()) return name;
  if (dir.back() == '/') return dir + name;
  return dir + "/" + name;
}

std::string formatTime(double t_s) {
  std::ostringstream os;
  os.setf(std::ios::fixed);
  os.precision(6);
  os << t_s;
  return os.str();
}

}  // namespace ltlo::io::detail
