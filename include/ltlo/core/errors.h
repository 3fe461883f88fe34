#pragma once
/// Project exceptions for bad input (STYLE.md section 7). Thrown by the reader that found the
/// problem, with the file, the line or key, and the value; Example mains print what() and exit 2.
#include <stdexcept>
#include <string>

namespace ltlo {

/// Bad data: a sequence file, an image, a trajectory. Message: "<file>:<line>: <what> (value)".
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
  /// Builds "<file>:<line>: <message>"; line <= 0 omits the line number.
  InputError(const std::string& file, int line, const std::string& message)
      : std::runtime_error(format(file, line, message)) {}

 private:
  static std::string format(const std::string& file, int line, const std::string& message) {
    return line > 0 ? file + ":" + std::to_string(line) + ": " + message : file + ": " + message;
  }
};

/// Bad settings: "config_yaml/tum_rgbd.yaml: Seg.Clusters = 1, expected an integer in [2, 256]".
class ConfigError : public std::runtime_error {
 public:
  explicit ConfigError(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace ltlo
