#pragma once
/// The error of a vocabulary file that cannot be read or is not a valid tree. bow includes nothing
/// from the project that uses it, so it has its own type; programs map it to their bad-input exit.
#include <stdexcept>
#include <string>

namespace bow {

/// Names the file, the byte offset of the offending field (-1 when the problem is not at one
/// place, e.g. the file is missing) and the value found there. what() reads
///   "<file>: byte <offset>: <problem> (<value>)"   or   "<file>: <problem>"
class FileError : public std::runtime_error {
 public:
  FileError(const std::string& path, long long offset, const std::string& problem,
            const std::string& value = "")
      : std::runtime_error(format(path, offset, problem, value)),
        path_(path),
        offset_(offset),
        value_(value) {}

  const std::string& path() const { return path_; }
  long long offset() const { return offset_; }  ///< -1 when not at one place
  const std::string& value() const { return value_; }

 private:
  static std::string format(const std::string& path, long long offset, const std::string& problem,
                            const std::string& value) {
    std::string text = path + ": ";
    if (offset >= 0) text += "byte " + std::to_string(offset) + ": ";
    text += problem;
    if (!value.empty()) text += " (" + value + ")";
    return text;
  }

  std::string path_;
  long long offset_;
  std::string value_;
};

}  // namespace bow
