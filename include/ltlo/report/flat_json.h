#pragma once
/// Reads flat JSON objects such as metrics.json ({"key": number | string | true | false | null}):
/// what io::Metrics writes and the benchmark report reads back. Nested values are rejected.
#include <map>
#include <optional>
#include <string>

namespace ltlo::report {

class FlatJson {
 public:
  /// Parses the file; throws InputError naming the file, the line and what was expected.
  static FlatJson read(const std::string& path);
  /// Parses text (`source` names it in messages).
  static FlatJson parse(const std::string& text, const std::string& source);

  /// The number under `key`; nullopt when absent, null or not a number (true/false are 1/0).
  std::optional<double> number(const std::string& key) const;
  std::optional<std::string> text(const std::string& key) const;
  bool has(const std::string& key) const { return numbers_.count(key) || texts_.count(key); }
  const std::map<std::string, double>& numbers() const { return numbers_; }

 private:
  std::map<std::string, double> numbers_;
  std::map<std::string, std::string> texts_;
};

}  // namespace ltlo::report
