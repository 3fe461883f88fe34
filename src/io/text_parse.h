#pragma once
// Line parsing shared by the io readers (private to ltlo_io). Every failure throws InputError
// naming the file, the line and the offending text.
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <istream>
#include <string>
#include <vector>

#include "ltlo/core/errors.h"

namespace ltlo::io::detail {

/// Reads a text file line by line as the readers accept it: CRLF or LF line ends (the '\r' is
/// dropped, so messages quote the line as written) and a UTF-8 byte order mark before line 1.
class LineReader {
 public:
  explicit LineReader(std::istream& in) : in_(in) {}
  /// Next line into line(); false at the end of the input.
  bool next();
  const std::string& line() const { return line_; }
  int number() const { return number_; }  ///< 1-based number of line()

 private:
  std::istream& in_;
  std::string line_;
  int number_ = 0;
};

/// True for empty, whitespace-only and '#' comment lines.
bool isCommentOrBlank(const std::string& line);

/// Splits on whitespace and on `separator` (e.g. ','), dropping empty fields.
std::vector<std::string> splitFields(const std::string& line, char separator = ' ');

/// Parses one finite number; `what` names the field in the message ("timestamp", "gx").
double parseFinite(const std::string& token, const std::string& what, const std::string& path,
                   int line_number);

/// Parses the first `count` fields of `line` as finite numbers; more fields are ignored when
/// `allow_extra`, otherwise they are an error.
std::vector<double> parseNumbers(const std::string& line, char separator, size_t count,
                                 bool allow_extra, const std::string& path, int line_number);

/// Parses a non-negative integer count of nanoseconds exactly and returns seconds.
double parseNanosecondsAsSeconds(const std::string& token, const std::string& path,
                                 int line_number);

/// "dir/name" without doubling the slash.
std::string joinPath(const std::string& dir, const std::string& name);

/// Timestamp text as in DATA_FORMAT.md (6 decimals) for messages.
std::string formatTime(double t_s);

/// Writes `path` through "<path>.part" renamed over it once complete, so the file is always the
/// previous or the whole new version (a run interrupted while writing leaves no half file).
/// `write_body(std::ostream&)` writes the content; throws InputError naming `path`.
template <typename WriteBody>
void writeAtomically(const std::string& path, WriteBody&& write_body) {
  const std::string part_path = path + ".part";
  {
    std::ofstream out(part_path);
    if (!out) throw InputError(path, 0, "cannot open for writing (" + part_path + ")");
    write_body(out);
    out.flush();
    if (!out) throw InputError(path, 0, "write failed (" + part_path + ")");
  }
  if (std::rename(part_path.c_str(), path.c_str()) != 0) {
    throw InputError(path, 0, "cannot rename " + part_path + " to it: " + std::strerror(errno));
  }
}

}  // namespace ltlo::io::detail
