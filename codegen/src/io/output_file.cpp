#include "kinegen/codegen/io/output_file.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <streambuf>
#include <vector>

#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/interrupt.hpp"

namespace kinegen::codegen {

namespace fs = std::filesystem;

namespace {

// Temporary files to remove if a signal ends the process. The handler may only read these
// fixed buffers; a slot is filled before it is marked in use and cleared before it is reused.
constexpr int kMaxPending = 4;
constexpr std::size_t kMaxPath = 4096;
struct PendingSlot {
  std::atomic<bool> used{false};
  char path[kMaxPath] = {};
};
std::array<PendingSlot, kMaxPending> g_pending;

// The first SIGINT asks the run to stop at its next interruption point (base/interrupt.hpp),
// which keeps what a streaming command wrote; a second one, or SIGTERM, SIGHUP, SIGQUIT, ends
// the process at once. Either way no temporary file is left behind.
extern "C" void remove_pending_and_reraise(int sig) {
  if (sig == SIGINT && !interrupt_requested()) {
    request_interrupt();
    return;
  }
  for (auto& slot : g_pending)
    if (slot.used.load()) ::unlink(slot.path);
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

int register_pending(const std::string& path) {
  if (path.size() >= kMaxPath) return -1;
  for (int k = 0; k < kMaxPending; ++k) {
    if (g_pending[k].used.load()) continue;
    std::memcpy(g_pending[k].path, path.c_str(), path.size() + 1);
    g_pending[k].used.store(true);
    return k;
  }
  return -1;
}

void unregister_pending(int slot) {
  if (slot >= 0) g_pending[slot].used.store(false);
}

std::string error_text(int err) { return std::strerror(err); }

// A stream buffer over a file descriptor that remembers the first error (errno) instead of
// dropping data silently.
class FdBuf : public std::streambuf {
 public:
  explicit FdBuf(int fd) : fd_(fd) { setp(buf_.data(), buf_.data() + buf_.size()); }
  int error() const { return error_; }
  bool flush_all() { return drain() && error_ == 0; }

 protected:
  int_type overflow(int_type ch) override {
    if (!drain()) return traits_type::eof();
    if (!traits_type::eq_int_type(ch, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(ch);
      pbump(1);
    }
    return traits_type::not_eof(ch);
  }
  int sync() override { return drain() ? 0 : -1; }

 private:
  bool drain() {
    const char* p = pbase();
    std::size_t left = static_cast<std::size_t>(pptr() - pbase());
    while (left > 0 && error_ == 0) {
      const ssize_t n = ::write(fd_, p, left);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        error_ = n < 0 ? errno : EIO;
        break;
      }
      p += n;
      left -= static_cast<std::size_t>(n);
    }
    setp(buf_.data(), buf_.data() + buf_.size());
    return error_ == 0;
  }

  int fd_;
  int error_ = 0;
  std::array<char, 1 << 16> buf_;
};

// Whether the path names something that must be written in place, never replaced: standard
// output under another name, and anything in /dev or /proc (device nodes, /dev/fd/N).
bool special_location(const fs::path& target) {
  std::error_code ec;
  const fs::path abs = fs::absolute(target, ec).lexically_normal();
  if (ec) return false;
  const std::string s = abs.string();
  return s.rfind("/dev/", 0) == 0 || s.rfind("/proc/", 0) == 0;
}

mode_t default_mode() {
  const mode_t mask = ::umask(0);
  ::umask(mask);
  return 0666 & ~mask;
}

}  // namespace

void install_signal_handlers() {
  for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) {
    struct sigaction old {};
    ::sigaction(sig, nullptr, &old);
    if (old.sa_handler == SIG_IGN) continue;  // nohup and friends keep their choice
    struct sigaction sa {};
    sa.sa_handler = remove_pending_and_reraise;
    sigemptyset(&sa.sa_mask);
    ::sigaction(sig, &sa, nullptr);  // no SA_RESTART: a blocked read or open returns EINTR
  }
}

struct OutputFile::Impl {
  std::string name;  // for messages
  fs::path target, temp;
  int fd = -1;
  bool owns_fd = false;  // not standard output
  bool committed = false;
  int slot = -1;
  std::unique_ptr<FdBuf> buf;
  std::unique_ptr<std::ostream> stream;

  [[noreturn]] void fail(const std::string& what, int err) const {
    throw OutputError(name + ": " + what + ": " + error_text(err));
  }

  void open_in_place(const std::string& path) {
    fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) throw UsageError("cannot write '" + name + "': " + error_text(errno));
    owns_fd = true;
  }

  void open_temp(mode_t mode) {
    const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
    std::string pattern = (dir / ("." + target.filename().string() + ".kinegen-XXXXXX")).string();
    // The file is created and registered for removal with the ending signals held: one that
    // came in between (a loaded machine can preempt the process there for milliseconds)
    // would leave the file behind. A held signal is delivered once they are released.
    sigset_t ending, before;
    sigemptyset(&ending);
    for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) sigaddset(&ending, sig);
    ::pthread_sigmask(SIG_BLOCK, &ending, &before);
    fd = ::mkostemp(pattern.data(), O_CLOEXEC);
    const int err = errno;
    if (fd >= 0) slot = register_pending(pattern);
    ::pthread_sigmask(SIG_SETMASK, &before, nullptr);
    if (fd < 0) throw UsageError("cannot write '" + name + "': " + error_text(err));
    owns_fd = true;
    temp = pattern;
    ::fchmod(fd, mode);
  }
};

OutputFile::OutputFile(const std::string& target) : impl_(std::make_unique<Impl>()) {
  Impl& d = *impl_;
  d.target = target;
  d.name = target;
  if (target == "-" || target == "/dev/stdout") {
    d.name = "standard output";
    d.fd = STDOUT_FILENO;
  } else if (target.empty()) {
    throw UsageError("an output file name must not be empty");
  } else {
    struct stat link {};
    const bool exists = ::lstat(target.c_str(), &link) == 0;
    struct stat st {};
    const bool resolves = exists && ::stat(target.c_str(), &st) == 0;
    if (exists && S_ISDIR(resolves ? st.st_mode : link.st_mode))
      throw UsageError("cannot write '" + target + "': it is a directory");
    if (special_location(target) || (resolves && !S_ISREG(st.st_mode))) {
      d.open_in_place(target);  // a device, a pipe, a socket: written through
    } else {
      // A regular file keeps its permissions; a link is replaced by a file of the default ones.
      d.open_temp(exists && S_ISREG(link.st_mode) ? (link.st_mode & 0777) : default_mode());
    }
  }
  d.buf = std::make_unique<FdBuf>(d.fd);
  d.stream = std::make_unique<std::ostream>(d.buf.get());
}

OutputFile::~OutputFile() {
  Impl& d = *impl_;
  if (d.committed) return;
  if (d.owns_fd && d.fd >= 0) ::close(d.fd);
  if (!d.temp.empty()) ::unlink(d.temp.c_str());
  unregister_pending(d.slot);
}

std::ostream& OutputFile::stream() { return *impl_->stream; }

const std::string& OutputFile::name() const { return impl_->name; }

bool OutputFile::replaces_target() const { return !impl_->temp.empty(); }

void OutputFile::check() {
  if (impl_->buf->error() != 0) impl_->fail("write failed", impl_->buf->error());
}

void OutputFile::commit() {
  Impl& d = *impl_;
  if (!d.buf->flush_all()) d.fail("write failed", d.buf->error());
  if (!d.temp.empty()) {
    if (::fsync(d.fd) != 0) d.fail("fsync failed", errno);
  }
  if (d.owns_fd) {
    const int fd = d.fd;
    d.fd = -1;
    if (::close(fd) != 0 && errno != EINTR) d.fail("close failed", errno);
  }
  if (!d.temp.empty()) {
    if (::rename(d.temp.c_str(), d.target.c_str()) != 0) d.fail("cannot rename into place", errno);
    d.temp.clear();
    unregister_pending(d.slot);
    d.slot = -1;
  }
  d.committed = true;
}

}  // namespace kinegen::codegen
