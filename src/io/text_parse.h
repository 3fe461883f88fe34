#pragma once
// Line parsing shared by the io readers (private to ltlo_io). Every failure throws InputError
// naming the file, the line and the offending text.
#include <string>
#include <vector>

namespace ltlo::io::detail {

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

}  // namespace ltlo::io::detail
