#include "ltlo/core/thread_names.h"

#include <algorithm>
#include <iterator>
#include <mutex>
#include <set>

namespace ltlo {
namespace {

struct Registry {
  std::mutex mutex;  // guards names
  std::multiset<std::string> names;
};

/// Never destroyed: threads may end after static destruction began.
Registry& registry() {
  static Registry* const instance = new Registry();
  return *instance;
}

/// The calling thread's entry; its destructor runs when the thread ends, before a joiner returns.
struct Registration {
  std::multiset<std::string>::iterator entry;
  bool registered = false;

  ~Registration() {
    if (!registered) return;
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    r.names.erase(entry);
  }
};

}  // namespace

namespace detail {

void registerNamedThread(const std::string& os_name) {
  thread_local Registration registration;
  Registry& r = registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  if (registration.registered) r.names.erase(registration.entry);
  registration.entry = r.names.insert(os_name);
  registration.registered = true;
}

}  // namespace detail

std::vector<std::string> runningNamedThreads() {
  Registry& r = registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  return std::vector<std::string>(r.names.begin(), r.names.end());
}

}  // namespace ltlo
