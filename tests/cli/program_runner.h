#pragma once
// Runs a built program as a child process for the command-line tests: collects stdout and stderr
// (read concurrently, so neither pipe fills), the exit code or the terminating signal, and can
// act once a line of stderr matches (e.g. send SIGINT after a progress line). No sleeps: the
// caller synchronises on the program's own output.
#include <functional>
#include <string>
#include <vector>

namespace ltlo::cli_test {

struct ProgramResult {
  int exit_code = -1;  ///< exit status when the program exited, -1 when a signal ended it
  int signal = 0;      ///< the terminating signal, 0 when the program exited
  std::string out;     ///< stdout
  std::string err;     ///< stderr

  /// "exit 2" or "signal 6 (...)" for failure messages, with the stderr tail.
  std::string describe() const;
};

/// Called with each complete stderr line and the child's pid; may signal the child.
using LineHook = std::function<void(const std::string& line, int pid)>;

/// Runs `argv` (argv[0] is the program path) with the working directory `cwd` (empty: unchanged).
ProgramResult runProgram(const std::vector<std::string>& argv, const std::string& cwd = "",
                         const LineHook& on_stderr_line = {});

/// build/bin/<name> of the tree the test was built in.
std::string programPath(const std::string& name);
/// The source tree (config_yaml/, Vocabulary/).
std::string sourceDir();

}  // namespace ltlo::cli_test
