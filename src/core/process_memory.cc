#include "ltlo/core/process_memory.h"

#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>

namespace ltlo {

double peakResidentMb() {
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0.0;
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux reports KiB
}

double currentResidentMb() {
  std::FILE* statm = std::fopen("/proc/self/statm", "r");
  if (statm == nullptr) return 0.0;
  unsigned long size_pages = 0, resident_pages = 0;
  const int read = std::fscanf(statm, "%lu %lu", &size_pages, &resident_pages);
  std::fclose(statm);
  if (read != 2) return 0.0;
  const long page_bytes = sysconf(_SC_PAGESIZE);
  return static_cast<double>(resident_pages) * static_cast<double>(page_bytes > 0 ? page_bytes : 4096) /
         (1024.0 * 1024.0);
}

}  // namespace ltlo
