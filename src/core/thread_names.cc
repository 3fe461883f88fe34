#include "ltlo/core/thread_names.h"

#include <filesystem>
#include <fstream>

namespace ltlo {

std::vector<std::string> runningNamedThreads() {
  std::vector<std::string> names;
  std::error_code error;
  for (std::filesystem::directory_iterator it("/proc/self/task", error), end; !error && it != end;
       it.increment(error)) {
    std::ifstream comm(it->path() / "comm");
    std::string name;
    if (std::getline(comm, name) && name.rfind(kThreadNamePrefix, 0) == 0) names.push_back(name);
  }
  return names;
}

}  // namespace ltlo
