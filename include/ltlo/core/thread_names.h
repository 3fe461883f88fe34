#pragma once
/// OS-visible names of the project's threads. log::setThreadName() also names a thread other than
/// the process' main thread "ltlo.<name>" for the OS (Linux, 15 characters at most), so top -H,
/// gdb and runningNamedThreads() see it.
#include <string>
#include <vector>

namespace ltlo {

/// Prefix of the OS names our threads get.
constexpr const char kThreadNamePrefix[] = "ltlo.";

/// OS names of this process' live threads named by log::setThreadName ("ltlo.mapping", ...), read
/// from /proc/self/task; programs check it after shutdown (no thread of ours left running).
/// Empty where /proc is not available.
std::vector<std::string> runningNamedThreads();

}  // namespace ltlo
