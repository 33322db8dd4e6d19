// Every file the library reads (the mechanism file, a table's or an input's CSV, a run's CSV,
// a modes JSON) is read with a bound, whatever it is: a regular file, a device (/dev/zero), a
// FIFO, standard input (/dev/stdin). A read stops at the bound and is refused beyond it, so
// memory stays bounded; a directory is named as one. The bounds are constants below
// (docs/cli.md: "Limits").
#pragma once

#include <cstddef>
#include <istream>
#include <string>

namespace kinegen::codegen {

// A mechanism file: far larger than any mechanism (the largest example is 12 KiB).
inline constexpr std::size_t kMaxMechanismBytes = std::size_t{1} << 20;
// A modes JSON (kinegen view --modes): q and the shapes, nq (modes + 1) numbers.
inline constexpr std::size_t kMaxModesBytes = std::size_t{16} << 20;
// One line of a run's CSV (kinegen view --csv), whose length is not otherwise bounded.
inline constexpr std::size_t kMaxCsvLineBytes = std::size_t{1} << 20;
// A run's CSV that is not a regular file (a pipe, standard input): held in memory to be read
// twice. A regular file is read from the disk, of any length.
inline constexpr std::size_t kMaxStreamedRunBytes = std::size_t{256} << 20;

struct FileText {
  enum class Status { kOk, kCannotOpen, kDirectory, kTooLarge, kReadError };
  Status status = Status::kOk;
  int error = 0;  // errno for kCannotOpen and kReadError
  std::string text;
  bool ok() const { return status == Status::kOk; }
  // What went wrong, for a message about `what` ("the mechanism file", "the table file 'x'"):
  // "cannot open the mechanism file: No such file or directory", "... is a directory", "... is
  // larger than 1048576 bytes (1 MiB)".
  std::string problem(const std::string& what, std::size_t limit) const;
};

// Reads at most `limit` bytes of `path`; a file with more is kTooLarge (its text is then
// empty), found after reading at most limit + 1 bytes.
FileText read_bounded(const std::string& path, std::size_t limit);

// std::getline that stops at `limit` characters: false at the end of the input; a longer line
// sets *too_long and returns true with the line cut at the limit (the rest is not read).
bool getline_bounded(std::istream& in, std::string& line, std::size_t limit, bool* too_long);

}  // namespace kinegen::codegen
