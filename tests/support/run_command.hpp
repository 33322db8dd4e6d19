// Runs a program (no shell: the arguments go to execv unchanged) and captures its exit status,
// standard output and standard error, for end-to-end tests of the kinegen binary.
//
// Header-only, POSIX. Output goes to unlinked temporary files rather than pipes, so a child
// that writes a lot to both streams cannot deadlock against the reader.
#ifndef KINEGEN_TESTS_SUPPORT_RUN_COMMAND_HPP
#define KINEGEN_TESTS_SUPPORT_RUN_COMMAND_HPP

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace kinegen::test {

struct CommandResult {
  int exit_code = -1;  // the exit status, or 128 + signal number when killed by a signal
  std::string out;     // standard output
  std::string err;     // standard error
};

namespace detail {

// An anonymous temporary file: created, unlinked at once, read back through its descriptor.
inline int anonymous_file() {
  std::string name = (std::filesystem::temp_directory_path() / "kinegen_test_XXXXXX").string();
  const int fd = ::mkstemp(name.data());
  if (fd < 0) throw std::runtime_error("run_command: mkstemp failed");
  ::unlink(name.c_str());
  return fd;
}

inline std::string read_all(int fd) {
  std::string text;
  if (::lseek(fd, 0, SEEK_SET) < 0) throw std::runtime_error("run_command: lseek failed");
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw std::runtime_error("run_command: read failed");
    if (n == 0) break;
    text.append(buf, static_cast<std::size_t>(n));
  }
  return text;
}

}  // namespace detail

// Runs args[0] (a path, not looked up in PATH) with args[1..], standard input from /dev/null,
// in directory `cwd` when it is not empty.
inline CommandResult run_command(const std::vector<std::string>& args,
                                 const std::string& cwd = {}) {
  if (args.empty()) throw std::invalid_argument("run_command: no program");
  // Everything the child needs is prepared before fork: it only calls async-signal-safe code.
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const int out_fd = detail::anonymous_file();
  const int err_fd = detail::anonymous_file();
  const int null_fd = ::open("/dev/null", O_RDONLY);

  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("run_command: fork failed");
  if (pid == 0) {
    if (null_fd < 0 || ::dup2(null_fd, STDIN_FILENO) < 0 || ::dup2(out_fd, STDOUT_FILENO) < 0 ||
        ::dup2(err_fd, STDERR_FILENO) < 0)
      ::_exit(126);
    if (!cwd.empty() && ::chdir(cwd.c_str()) != 0) ::_exit(126);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) throw std::runtime_error("run_command: waitpid failed");
  }
  CommandResult result;
  if (WIFEXITED(status)) result.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) result.exit_code = 128 + WTERMSIG(status);
  result.out = detail::read_all(out_fd);
  result.err = detail::read_all(err_fd);
  ::close(out_fd);
  ::close(err_fd);
  if (null_fd >= 0) ::close(null_fd);
  return result;
}

// AddressSanitizer reserves terabytes of address space for its shadow memory, so a child built
// with it cannot run under an address-space limit; the ordinary build checks the memory bound.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kLimitAddressSpace = false;
#else
constexpr bool kLimitAddressSpace = true;
#endif

// A child started now and waited for later (so that a test can signal it meanwhile): argv[0]
// (a path) with argv[1..], standard input from `in_path`, standard output appended to
// `out_path`, standard error to `err_path`, and optionally bounded CPU time and address space:
// a run that would abort, swap or take minutes fails the test instead.
struct ChildProcess {
  pid_t pid = -1;

  ChildProcess(const std::vector<std::string>& args, const std::string& in_path,
               const std::string& out_path, const std::string& err_path, rlim_t cpu_seconds = 0,
               rlim_t address_bytes = 0) {
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    pid = ::fork();
    if (pid < 0) throw std::runtime_error("ChildProcess: fork failed");
    if (pid == 0) {
      const int out = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      const int er = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int in = ::open(in_path.c_str(), O_RDONLY);
      if (out < 0 || er < 0 || in < 0 || ::dup2(out, 1) < 0 || ::dup2(er, 2) < 0 ||
          ::dup2(in, 0) < 0)
        ::_exit(126);
      if (cpu_seconds) {
        const rlimit cpu{cpu_seconds, cpu_seconds};
        ::setrlimit(RLIMIT_CPU, &cpu);
      }
      if (address_bytes && kLimitAddressSpace) {
        const rlimit as{address_bytes, address_bytes};
        ::setrlimit(RLIMIT_AS, &as);
      }
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
  }
  // The exit status, or 128 + the signal.
  int wait() {
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0)
      if (errno != EINTR) return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
};

}  // namespace kinegen::test

#endif  // KINEGEN_TESTS_SUPPORT_RUN_COMMAND_HPP
