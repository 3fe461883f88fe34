#include "ltlo/core/thread_priority.h"

#include <cerrno>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

namespace ltlo {
namespace {

id_t currentThreadId() { return static_cast<id_t>(::syscall(SYS_gettid)); }

}  // namespace

int currentThreadNice() {
  errno = 0;
  const int nice = ::getpriority(PRIO_PROCESS, currentThreadId());
  return errno == 0 ? nice : 0;
}

int lowerCurrentThreadPriority(int increment) {
  const int nice = currentThreadNice();
  if (increment <= 0) return nice;
  const int wanted = nice + increment > 19 ? 19 : nice + increment;
  if (::setpriority(PRIO_PROCESS, currentThreadId(), wanted) != 0) return nice;
  return currentThreadNice();
}

}  // namespace ltlo
