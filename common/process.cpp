#include "dentmark/common/process.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string_view>

extern char** environ;

namespace dentmark::process {
namespace {

// The program's path: argv[0] itself when it names a path, else the first executable
// of that name on PATH. Resolved here, not by posix_spawnp, so that a missing program is
// an error everywhere (under qemu-user a failed exec shows only as the child's exit 127).
std::string resolve(const std::string& program) {
  if (program.find('/') != std::string::npos) {
    if (::access(program.c_str(), X_OK) != 0)
      throw ProcessError(program + ": cannot run: " + std::strerror(errno));
    return program;
  }
  const char* env = std::getenv("PATH");
  std::string_view dirs = env && *env ? env : "/usr/local/bin:/usr/bin:/bin";
  for (;;) {
    const std::size_t end = dirs.find(':');
    const std::string_view dir = dirs.substr(0, end);
    const std::filesystem::path candidate =
        std::filesystem::path(dir.empty() ? std::string_view(".") : dir) / program;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    if (end == std::string_view::npos) break;
    dirs.remove_prefix(end + 1);
  }
  throw ProcessError(program + ": cannot run: not found on PATH");
}

}  // namespace

Result run(const std::vector<std::string>& argv, double timeout) {
  if (argv.empty()) throw ProcessError("no program to run");
  const std::string program = resolve(argv[0]);
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0)
    throw ProcessError(argv[0] + ": cannot make a pipe: " + std::strerror(errno));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], STDERR_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  const int rc = ::posix_spawn(&pid, program.c_str(), &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(pipe_fds[1]);
  if (rc != 0) {
    ::close(pipe_fds[0]);
    throw ProcessError(argv[0] + ": cannot run: " + std::strerror(rc));
  }
  using steady = std::chrono::steady_clock;
  const auto deadline = steady::now() + std::chrono::duration_cast<steady::duration>(
                                            std::chrono::duration<double>(timeout > 0.0 ? timeout : 0.0));
  Result result;
  char buf[4096];
  for (;;) {
    int wait_ms = -1;
    if (timeout > 0.0) {
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - steady::now()).count();
      if (left <= 0) {
        ::kill(pid, SIGKILL);  // a hung tool (an ssh to a box that went away) ends here
        result.timed_out = true;
        break;
      }
      wait_ms = static_cast<int>(std::min<long long>(left, 1000));
    }
    pollfd p{pipe_fds[0], POLLIN, 0};
    const int ready = ::poll(&p, 1, wait_ms);
    if (ready < 0 && errno == EINTR) continue;
    if (ready == 0) continue;
    const ssize_t n = ::read(pipe_fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    result.output.append(buf, static_cast<std::size_t>(n));
  }
  ::close(pipe_fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return result;
}

}  // namespace dentmark::process
