#include "ltlo/core/settings_file.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"

namespace ltlo {
namespace {

std::string rangeText(double min, double max) {
  std::ostringstream os;
  os << "[" << min << ", " << max << "]";
  return os.str();
}

}  // namespace

SettingsFile::SettingsFile(const std::string& path) : path_(path) {
  // Checked first so that a missing file gives our message only (OpenCV would also log one).
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) throw ConfigError(path + ": is a folder, not a settings file");
  if (!std::ifstream(path).good()) throw ConfigError(path + ": cannot open settings file");
  try {
    if (!storage_.open(path, cv::FileStorage::READ)) {
      throw ConfigError(path + ": cannot open settings file");
    }
    root_ = storage_.root();
  } catch (const cv::Exception& e) {
    throw ConfigError(path + ": cannot parse settings file (" + e.msg + ")");
  } catch (const std::exception& e) {
    // OpenCV 4.6's YAML parser can also fail with a standard exception on malformed input (a
    // fuzzed key before "data:" of a matrix gave std::length_error from inside the parser).
    throw ConfigError(path + ": cannot parse settings file (" + e.what() + ")");
  }
  // Keys are looked up in the top-level map; OpenCV asserts on a lookup in anything else.
  if (root_.empty() || root_.isNone()) throw ConfigError(path + ": settings file has no keys");
  if (!root_.isMap()) {
    throw ConfigError(path + ": top level is " + describe(root_) + ", expected a map of \"Key: value\" lines");
  }
}

cv::FileNode SettingsFile::lookup(const std::string& key) const {
  const auto it = overrides_.find(key);
  return it != overrides_.end() ? it->second[key] : root_[key];
}

cv::FileNode SettingsFile::node(const std::string& key) const {
  read_keys_.insert(key);
  return lookup(key);
}

bool SettingsFile::has(const std::string& key) const {
  const cv::FileNode n = lookup(key);
  return !n.empty() && !n.isNone();
}

void SettingsFile::setOverride(const std::string& key, const std::string& value_text) {
  const bool key_ok = !key.empty() && std::all_of(key.begin(), key.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_';
  });
  if (!key_ok) {
    throw ConfigError(path_ + " (--set): key \"" + key + "\", expected letters, digits, '.' and '_'");
  }
  const std::string expected = "one YAML scalar (a number, 0/1, true/false or a string)";
  if (value_text.empty() || value_text.find_first_of("\n\r{}[]#") != std::string::npos) {
    throw ConfigError(path_ + " (--set): " + key + " = \"" + value_text + "\", expected " + expected);
  }
  // As the file would read "key: value"; text OpenCV's YAML cannot read unquoted (320x240) is
  // taken as the string it would be in quotes.
  auto parse = [&](const std::string& text) {
    cv::FileStorage storage;
    try {
      storage.open("%YAML:1.0\n" + key + ": " + text + "\n", cv::FileStorage::READ | cv::FileStorage::MEMORY);
    } catch (const cv::Exception&) {
      storage.release();
    }
    return storage;
  };
  cv::FileStorage storage = parse(value_text);
  if (!storage.isOpened() && value_text.find_first_of("\"\\") == std::string::npos) {
    storage = parse("\"" + value_text + "\"");
  }
  const cv::FileNode n = storage.isOpened() ? storage[key] : cv::FileNode();
  if (n.empty() || n.isNone() || n.isMap() || n.isSeq()) {
    throw ConfigError(path_ + " (--set): " + key + " = \"" + value_text + "\", expected " + expected);
  }
  overrides_[key] = std::move(storage);
}

std::string SettingsFile::describe(const cv::FileNode& n) {
  if (n.isString()) return "\"" + static_cast<std::string>(n) + "\"";
  if (n.isInt()) return std::to_string(static_cast<int>(n));
  if (n.isReal()) {
    std::ostringstream os;
    os << static_cast<double>(n);
    return os.str();
  }
  if (n.isMap()) return "a map";
  if (n.isSeq()) return "a sequence";
  return "an empty value";
}

void SettingsFile::fail(const std::string& key, const std::string& value,
                        const std::string& expected) const {
  const std::string source = overrides_.count(key) > 0 ? path_ + " (--set)" : path_;
  throw ConfigError(source + ": " + key + " = " + value + ", expected " + expected);
}

void SettingsFile::failMissing(const std::string& key, const std::string& expected) const {
  throw ConfigError(path_ + ": missing key " + key + ", expected " + expected);
}

std::string SettingsFile::valueText(const std::string& key) const { return describe(lookup(key)); }

double SettingsFile::getDouble(const std::string& key, double min, double max) const {
  const cv::FileNode n = node(key);
  const std::string expected = "a number in " + rangeText(min, max);
  if (n.empty() || n.isNone()) failMissing(key, expected);
  if (!n.isReal() && !n.isInt()) fail(key, describe(n), expected);
  const double value = static_cast<double>(n);
  if (!std::isfinite(value) || value < min || value > max) fail(key, describe(n), expected);
  return value;
}

int SettingsFile::getInt(const std::string& key, int min, int max) const {
  const cv::FileNode n = node(key);
  const std::string expected = "an integer in " + rangeText(min, max);
  if (n.empty() || n.isNone()) failMissing(key, expected);
  if (!n.isInt()) fail(key, describe(n), expected);
  const int value = static_cast<int>(n);
  if (value < min || value > max) fail(key, describe(n), expected);
  return value;
}

bool SettingsFile::getBool(const std::string& key) const {
  const cv::FileNode n = node(key);
  const std::string expected = "a boolean (0/1 or true/false)";
  if (n.empty() || n.isNone()) failMissing(key, expected);
  if (n.isInt()) {
    const int value = static_cast<int>(n);
    if (value == 0 || value == 1) return value == 1;
  } else if (n.isString()) {
    const std::string value = static_cast<std::string>(n);
    if (value == "true") return true;
    if (value == "false") return false;
  }
  fail(key, describe(n), expected);
}

std::string SettingsFile::getString(const std::string& key) const {
  const cv::FileNode n = node(key);
  if (n.empty() || n.isNone()) failMissing(key, "a string");
  if (!n.isString()) fail(key, describe(n), "a string");
  return static_cast<std::string>(n);
}

MatX SettingsFile::getMatrix(const std::string& key, int rows, int cols) const {
  const cv::FileNode n = node(key);
  const std::string expected =
      "a " + std::to_string(rows) + "x" + std::to_string(cols) + " !!opencv-matrix of finite numbers";
  if (n.empty() || n.isNone()) failMissing(key, expected);
  // The !!opencv-matrix fields are checked before OpenCV reads the node: it sizes the matrix from
  // rows and cols as written (a corrupt count asked it for 64 GB, a fuzzing finding).
  if (!n.isMap()) fail(key, describe(n), expected);
  const cv::FileNode rows_node = n["rows"], cols_node = n["cols"], data_node = n["data"];
  if (!rows_node.isInt() || !cols_node.isInt() || !n["dt"].isString() || !data_node.isSeq()) {
    fail(key, "a map without integer rows, cols, a dt string and a data list", expected);
  }
  const int file_rows = static_cast<int>(rows_node), file_cols = static_cast<int>(cols_node);
  if (file_rows != rows || file_cols != cols) {
    fail(key, std::to_string(file_rows) + "x" + std::to_string(file_cols) + " matrix", expected);
  }
  if (data_node.size() != static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols)) {
    fail(key, "a matrix with " + std::to_string(data_node.size()) + " data values", expected);
  }
  cv::Mat m;
  try {
    n >> m;
  } catch (const cv::Exception&) {
    fail(key, describe(n), expected);
  }
  if (m.empty()) fail(key, describe(n), expected);
  if (m.rows != rows || m.cols != cols) {
    fail(key, std::to_string(m.rows) + "x" + std::to_string(m.cols) + " matrix", expected);
  }
  cv::Mat m64;
  m.convertTo(m64, CV_64F);
  MatX out(rows, cols);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const double value = m64.at<double>(r, c);
      if (!std::isfinite(value)) {
        std::ostringstream os;
        os << "matrix with element (" << r << ", " << c << ") = " << value;
        fail(key, os.str(), expected);
      }
      out(r, c) = value;
    }
  }
  return out;
}

double SettingsFile::getDouble(const std::string& key, double default_value, double min,
                               double max) const {
  read_keys_.insert(key);
  return has(key) ? getDouble(key, min, max) : default_value;
}

int SettingsFile::getInt(const std::string& key, int default_value, int min, int max) const {
  read_keys_.insert(key);
  return has(key) ? getInt(key, min, max) : default_value;
}

bool SettingsFile::getBool(const std::string& key, bool default_value) const {
  read_keys_.insert(key);
  return has(key) ? getBool(key) : default_value;
}

std::string SettingsFile::getString(const std::string& key, const std::string& default_value) const {
  read_keys_.insert(key);
  return has(key) ? getString(key) : default_value;
}

std::vector<std::string> SettingsFile::unreadKeys() const {
  std::vector<std::string> unread;
  for (auto it = root_.begin(); it != root_.end(); ++it) {
    const std::string name = (*it).name();
    if (read_keys_.count(name) == 0) unread.push_back(name);
  }
  for (const auto& [key, storage] : overrides_) {
    if (read_keys_.count(key) == 0 && root_[key].empty()) unread.push_back(key);
  }
  return unread;
}

void SettingsFile::warnUnreadKeys() const {
  for (const std::string& key : unreadKeys()) {
    log::warn(path_, ": unknown key ", key, " (ignored; a typo?)");
  }
}

}  // namespace ltlo
