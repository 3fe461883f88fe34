#pragma once
/// Named result values printed as "name value" lines and written as a flat JSON object with the
/// same keys (evaluate's output, the SLAM program's metrics.json).
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

namespace ltlo::io {

/// Ordered list of named values; keys keep insertion order, adding a key twice replaces it.
class Metrics {
 public:
  using Value = std::variant<int64_t, double, std::string, bool>;

  void set(const std::string& name, double value);
  void set(const std::string& name, int64_t value);
  void set(const std::string& name, int value) { set(name, static_cast<int64_t>(value)); }
  void set(const std::string& name, const std::string& value);
  void set(const std::string& name, const char* value) { set(name, std::string(value)); }
  /// A yes/no value: JSON true/false, text "true"/"false", number() 1/0.
  void setFlag(const std::string& name, bool value);

  bool has(const std::string& name) const;
  /// The value as a number, a flag as 1/0 (throws std::out_of_range when absent or a string).
  double number(const std::string& name) const;
  const std::vector<std::pair<std::string, Value>>& entries() const { return entries_; }

  /// One "name value" per line; doubles with 9 significant digits, non-finite as "nan"/"inf".
  std::string toText() const;
  /// {"name": value, ...}; doubles with 17 significant digits, non-finite as null.
  std::string toJson() const;
  /// Writes toJson() to `path` (through "<path>.part", renamed when complete); throws InputError
  /// when the file cannot be written.
  void writeJson(const std::string& path) const;

 private:
  void setValue(const std::string& name, Value value);
  std::vector<std::pair<std::string, Value>> entries_;
};

}  // namespace ltlo::io
