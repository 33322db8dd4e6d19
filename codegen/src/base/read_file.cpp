#include "kinegen/codegen/base/read_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "kinegen/codegen/base/interrupt.hpp"

namespace kinegen::codegen {

std::string FileText::problem(const std::string& what, std::size_t limit) const {
  switch (status) {
    case Status::kOk:
      return "";
    case Status::kCannotOpen:
      return "cannot open " + what + ": " + std::strerror(error);
    case Status::kDirectory:
      return what + " is a directory, not a file";
    case Status::kTooLarge: {
      std::string size = std::to_string(limit) + " bytes";
      if (limit % (std::size_t{1} << 20) == 0) size += " (" + std::to_string(limit >> 20) + " MiB)";
      return what + " is larger than " + size;
    }
    case Status::kReadError:
      return "cannot read " + what + ": " + std::strerror(error);
  }
  return "";
}

FileText read_bounded(const std::string& path, std::size_t limit) {
  FileText out;
  // A FIFO without a writer blocks here, as it does for cat; a signal stops it (EINTR).
  int fd = -1;
  while ((fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOCTTY)) < 0 && errno == EINTR)
    interruption_point();
  if (fd < 0) {
    out.status = errno == EISDIR ? FileText::Status::kDirectory : FileText::Status::kCannotOpen;
    out.error = errno;
    return out;
  }
  struct stat st {};
  if (::fstat(fd, &st) == 0 && S_ISDIR(st.st_mode)) {
    ::close(fd);
    out.status = FileText::Status::kDirectory;
    return out;
  }
  // A regular file says its size; anything else is read until the bound.
  if (S_ISREG(st.st_mode) && static_cast<std::size_t>(st.st_size) > limit) {
    ::close(fd);
    out.status = FileText::Status::kTooLarge;
    return out;
  }
  char buffer[1 << 16];
  while (true) {
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) {
      interruption_point();
      continue;
    }
    if (n < 0) {
      out.status = FileText::Status::kReadError;
      out.error = errno;
      out.text.clear();
      break;
    }
    if (n == 0) break;
    if (out.text.size() + static_cast<std::size_t>(n) > limit) {
      out.status = FileText::Status::kTooLarge;
      out.text = std::string();
      break;
    }
    out.text.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fd);
  return out;
}

bool getline_bounded(std::istream& in, std::string& line, std::size_t limit, bool* too_long) {
  line.clear();
  *too_long = false;
  std::streambuf* buf = in.rdbuf();
  bool any = false;
  while (true) {
    const int ch = buf->sbumpc();
    if (ch == std::char_traits<char>::eof()) {
      if (!any) in.setstate(std::ios::eofbit | std::ios::failbit);
      return any;
    }
    any = true;
    if (ch == '\n') return true;
    if (line.size() >= limit) {
      *too_long = true;
      return true;
    }
    line.push_back(static_cast<char>(ch));
  }
}

}  // namespace kinegen::codegen
