// Resources shared by the tests of one end-to-end suite: a temporary folder for the sequences the
// simulator writes and the runs' outputs (removed when the suite ends), and the shipped vocabulary,
// loaded once per suite.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

#include "bow/vocabulary.h"

namespace ltlo::test_support {

/// The source tree: LTLO_SOURCE_DIR (set by ctest) or the working folder.
inline std::filesystem::path sourceDir() {
  const char* root = std::getenv("LTLO_SOURCE_DIR");
  return root != nullptr ? std::filesystem::path(root) : std::filesystem::current_path();
}

/// Base of the end-to-end fixtures. A derived suite calls createSuiteResources(prefix) from its
/// SetUpTestSuite and removeSuiteResources() from its TearDownTestSuite.
class EndToEndSuite : public ::testing::Test {
 protected:
  /// Creates <tmp>/<prefix><pid>/ and loads Vocabulary/ltlo_orb_k10_L5.bin.
  static void createSuiteResources(const std::string& prefix) {
    root_ = std::filesystem::temp_directory_path() / (prefix + std::to_string(::getpid()));
    std::filesystem::create_directories(root_);
    vocabulary_ = std::make_shared<const bow::Vocabulary>(
        bow::Vocabulary::load((sourceDir() / "Vocabulary/ltlo_orb_k10_L5.bin").string()));
  }
  static void removeSuiteResources() {
    std::filesystem::remove_all(root_);
    root_.clear();
    vocabulary_.reset();
  }
  static const std::filesystem::path& root() { return root_; }
  static const std::shared_ptr<const bow::Vocabulary>& vocabulary() { return vocabulary_; }

 private:
  static inline std::filesystem::path root_;
  static inline std::shared_ptr<const bow::Vocabulary> vocabulary_;
};

}  // namespace ltlo::test_support
