#include "program_runner.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace ltlo::cli_test {
namespace {

void closeIfOpen(int* fd) {
  if (*fd >= 0) close(*fd);
  *fd = -1;
}

}  // namespace

std::string ProgramResult::describe() const {
  std::string text = signal != 0 ? "signal " + std::to_string(signal) + " (" + strsignal(signal) + ")"
                                 : "exit " + std::to_string(exit_code);
  const size_t tail_begin = err.size() > 2000 ? err.size() - 2000 : 0;
  return text + "; stderr tail:\n" + err.substr(tail_begin);
}

ProgramResult runProgram(const std::vector<std::string>& argv, const std::string& cwd,
                         const LineHook& on_stderr_line) {
  int out_pipe[2];
  int err_pipe[2];
  if (pipe2(out_pipe, O_CLOEXEC) != 0 || pipe2(err_pipe, O_CLOEXEC) != 0) {
    throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  }
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
  if (pid == 0) {
    dup2(out_pipe[1], STDOUT_FILENO);
    dup2(err_pipe[1], STDERR_FILENO);
    if (!cwd.empty() && chdir(cwd.c_str()) != 0) _exit(127);
    std::vector<char*> args;
    for (const std::string& arg : argv) args.push_back(const_cast<char*>(arg.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  close(out_pipe[1]);
  close(err_pipe[1]);
  int out_fd = out_pipe[0];
  int err_fd = err_pipe[0];
  ProgramResult result;
  std::string pending_line;
  char buffer[4096];
  while (out_fd >= 0 || err_fd >= 0) {
    pollfd fds[2] = {{out_fd, POLLIN, 0}, {err_fd, POLLIN, 0}};
    if (poll(fds, 2, -1) < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error(std::string("poll: ") + std::strerror(errno));
    }
    for (int i = 0; i < 2; ++i) {
      if (fds[i].fd < 0 || (fds[i].revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
      const ssize_t n = read(fds[i].fd, buffer, sizeof(buffer));
      if (n <= 0) {
        closeIfOpen(i == 0 ? &out_fd : &err_fd);
        continue;
      }
      if (i == 0) {
        result.out.append(buffer, static_cast<size_t>(n));
        continue;
      }
      result.err.append(buffer, static_cast<size_t>(n));
      pending_line.append(buffer, static_cast<size_t>(n));
      for (size_t end = pending_line.find('\n'); end != std::string::npos; end = pending_line.find('\n')) {
        const std::string line = pending_line.substr(0, end);
        pending_line.erase(0, end + 1);
        if (on_stderr_line) on_stderr_line(line, pid);
      }
    }
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status)) {
    result.exit_code = WEXITSTATUS(status);
  } else if (WIFSIGNALED(status)) {
    result.signal = WTERMSIG(status);
  }
  return result;
}

std::string programPath(const std::string& name) { return std::string(LTLO_CLI_BIN_DIR) + "/" + name; }

std::string sourceDir() { return LTLO_CLI_SOURCE_DIR; }

}  // namespace ltlo::cli_test
