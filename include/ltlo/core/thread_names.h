#pragma once
/// OS-visible names of the project's threads. log::setThreadName() also names a thread other than
/// the process' main thread "ltlo.<name>" for the OS (Linux, 15 characters at most), so top -H and
/// gdb see it, and registers it as live until the thread ends (runningNamedThreads()).
#include <string>
#include <vector>

namespace ltlo {

/// Prefix of the OS names our threads get.
constexpr const char kThreadNamePrefix[] = "ltlo.";

/// OS names of this process' live threads named by log::setThreadName ("ltlo.mapping", ...), in
/// name order; programs check it after shutdown (no thread of ours left running). A thread leaves
/// the list when its thread-local storage is destroyed, which happens before a join() on it
/// returns; /proc/self/task may still list a joined thread for a moment (the kernel wakes the
/// joiner before the task is gone), so it is not read.
std::vector<std::string> runningNamedThreads();

namespace detail {
/// Registers the calling thread under os_name until it ends (a second call renames it); used by
/// log::setThreadName.
void registerNamedThread(const std::string& os_name);
}  // namespace detail

}  // namespace ltlo
