#pragma once
/// Typed, validated access to one OpenCV FileStorage YAML settings file (ORB-SLAM3-style keys such
/// as "Camera.fx"). Every getter names the file, the key, the expected type and range and the value
/// found when it throws ConfigError (STYLE.md section 4):
///   "config_yaml/tum_rgbd.yaml: Seg.Clusters = 1, expected an integer in [2, 256]"
/// Keys that were never read can be listed afterwards to warn about typos.
/// Not thread-safe: load settings once, before the threads start.
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <opencv2/core/persistence.hpp>

#include "ltlo/core/eigen_types.h"

namespace ltlo {

class SettingsFile {
 public:
  /// Opens `path`; throws ConfigError when it cannot be read or parsed, or its top level is not a
  /// map of keys.
  explicit SettingsFile(const std::string& path);

  const std::string& path() const { return path_; }
  bool has(const std::string& key) const;

  /// Required keys: throw ConfigError when missing, of the wrong type or out of [min, max].
  double getDouble(const std::string& key, double min = -std::numeric_limits<double>::infinity(),
                   double max = std::numeric_limits<double>::infinity()) const;
  int getInt(const std::string& key, int min = std::numeric_limits<int>::min(),
             int max = std::numeric_limits<int>::max()) const;
  bool getBool(const std::string& key) const;  ///< 0/1 or true/false
  std::string getString(const std::string& key) const;
  /// A rows x cols !!opencv-matrix (any numeric type), returned as doubles.
  MatX getMatrix(const std::string& key, int rows, int cols) const;

  /// Optional keys: the default when missing, otherwise validated like the required getters.
  double getDouble(const std::string& key, double default_value, double min, double max) const;
  int getInt(const std::string& key, int default_value, int min, int max) const;
  bool getBool(const std::string& key, bool default_value) const;
  std::string getString(const std::string& key, const std::string& default_value) const;

  /// Replaces (or adds) `key` with `value_text` read as a YAML scalar, exactly as if the file said
  /// "key: value_text" ("3" is an integer, "0.5" a number, "abc" or "320x240" a string), so the
  /// getters validate it like a value of the file; their errors then name the file and "--set".
  /// Throws ConfigError on a malformed key or a value that is not one YAML scalar.
  void setOverride(const std::string& key, const std::string& value_text);
  /// Whether a getter has asked for `key` (read keys are known settings).
  bool wasRead(const std::string& key) const { return read_keys_.count(key) > 0; }

  /// Top-level keys present in the file (or overridden) that no getter has asked for (usually typos).
  std::vector<std::string> unreadKeys() const;
  /// Logs a warning per unread key.
  void warnUnreadKeys() const;

  /// The value of `key` as error messages quote it ("\"abc\"", "12", "a sequence", ...).
  std::string valueText(const std::string& key) const;

  /// "<path>: <key> = <value>, expected <expected>" as a ConfigError.
  [[noreturn]] void fail(const std::string& key, const std::string& value,
                         const std::string& expected) const;
  /// "<path>: missing key <key>, expected <expected>" as a ConfigError.
  [[noreturn]] void failMissing(const std::string& key, const std::string& expected) const;

 private:
  cv::FileNode node(const std::string& key) const;  // marks the key read; an override first
  cv::FileNode lookup(const std::string& key) const;  // an override first, no marking
  static std::string describe(const cv::FileNode& n);

  std::string path_;
  cv::FileStorage storage_;
  cv::FileNode root_;  // the top-level map every key is looked up in
  /// One in-memory YAML document "key: value" per overridden key.
  std::map<std::string, cv::FileStorage> overrides_;
  mutable std::set<std::string> read_keys_;
};

}  // namespace ltlo
