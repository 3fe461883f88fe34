#pragma once
/// LTLO_ASSERT(cond, message): programmer errors (STYLE.md section 7). On unless
/// LTLO_DISABLE_ASSERTS is defined (the CMake option LTLO_ENABLE_ASSERTS=OFF does that).
/// A failed assertion throws ltlo::AssertionError naming the condition, file and line, so a
/// thread's run() can log it and start an orderly shutdown that still writes the trajectory.
#include <sstream>
#include <stdexcept>
#include <string>

namespace ltlo {

class AssertionError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

namespace detail {
[[noreturn]] inline void assertionFailed(const char* cond, const char* file, int line,
                                         const std::string& message) {
  std::ostringstream os;
  os << file << ":" << line << ": assertion '" << cond << "' failed: " << message;
  throw AssertionError(os.str());
}
}  // namespace detail

}  // namespace ltlo

#ifdef LTLO_DISABLE_ASSERTS
#define LTLO_ASSERT(cond, message) ((void)0)
#else
#define LTLO_ASSERT(cond, message)                                                      \
  do {                                                                                  \
    if (!(cond)) {                                                                      \
      std::ostringstream ltlo_assert_os_;                                               \
      ltlo_assert_os_ << message;                                                       \
      ::ltlo::detail::assertionFailed(#cond, __FILE__, __LINE__, ltlo_assert_os_.str()); \
    }                                                                                   \
  } while (false)
#endif
