#pragma once
// Error-path helpers for tests: the text of the InputError a call throws, and a substring check
// that prints both strings when it fails.
#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "ltlo/core/errors.h"

namespace ltlo::test {

/// what() of the InputError thrown by f; records a test failure when f throws none.
inline std::string inputErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an InputError";
  return "";
}

}  // namespace ltlo::test

#define LTLO_EXPECT_CONTAINS(text, part)                     \
  EXPECT_NE(std::string(text).find(part), std::string::npos) \
      << "'" << (text) << "' lacks '" << (part) << "'"
