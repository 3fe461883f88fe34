// SettingsFile on files that are not a map of keys (found by fuzzing: OpenCV asserts when a key is
// looked up in a top-level sequence or scalar) and on paths that are not files.
#include "ltlo/core/settings_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "ltlo/core/calib.h"
#include "ltlo/core/errors.h"

namespace ltlo {
namespace {

namespace fs = std::filesystem;

class SettingsFileShapes : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("ltlo_settings_file_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// what() of the ConfigError that loading `text` as calib.yaml gives.
  std::string errorOf(const std::string& text) {
    const std::string path = (dir_ / "calib.yaml").string();
    std::ofstream(path) << text;
    try {
      SensorCalib::load(path);
    } catch (const ConfigError& e) {
      return e.what();
    }
    ADD_FAILURE() << "expected a ConfigError for:\n" << text;
    return "";
  }

  fs::path dir_;
};

TEST_F(SettingsFileShapes, TopLevelThatIsNotAMapIsAConfigErrorNamingTheFile) {
  const std::string path = (dir_ / "calib.yaml").string();
  EXPECT_EQ(errorOf("%YAML:1.0\n---\n- Camera.fx\n- 525\n"),
            path + ": top level is a sequence, expected a map of \"Key: value\" lines");
  EXPECT_EQ(errorOf("%YAML:1.0\n---\n[1, 2, 3]\n"),
            path + ": top level is a sequence, expected a map of \"Key: value\" lines");
  EXPECT_EQ(errorOf("%YAML:1.0\n---\n"), path + ": settings file has no keys");
  EXPECT_NE(errorOf("%YAML:1.0\n---\nCamera.fx: [1, 2\n").find(path + ": cannot parse settings file"),
            std::string::npos);
  // Found by fuzzing: OpenCV's parser throws std::length_error on this matrix header.
  EXPECT_NE(errorOf("%YAML:1.0\n---\nIMU.T_b_c1: !!opencv-matrix\n   rows: 4\n   cols: 4\n   :t \nd d  data: [ 0.5, "
                    "-0.1l -0.9ML:1.0\n---\nCamera.fx: 1\n")
                .find(path + ": cannot parse settings file"),
            std::string::npos);
}

TEST_F(SettingsFileShapes, FolderOrMissingPathIsAConfigError) {
  try {
    SettingsFile file(dir_.string());
    FAIL() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), dir_.string() + ": is a folder, not a settings file");
  }
  EXPECT_THROW(SettingsFile((dir_ / "missing.yaml").string()), ConfigError);
}

}  // namespace
}  // namespace ltlo
