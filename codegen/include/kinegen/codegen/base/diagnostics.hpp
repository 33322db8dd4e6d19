// Errors that reach the user as one `error:` line.
#pragma once

#include <stdexcept>
#include <string>

namespace kinegen::codegen {

// A place in a mechanism file; line and column are 1-based, 0 when unknown.
struct SourceLoc {
  int line = 0;
  int column = 0;
};

// Bad input: the file, the offending item and its line. Exit status 2.
class InputError : public std::runtime_error {
 public:
  InputError(std::string file, std::string item, SourceLoc loc, const std::string& message);

  const std::string& file() const { return file_; }
  const std::string& item() const { return item_; }
  SourceLoc loc() const { return loc_; }
  const std::string& detail() const { return detail_; }

 private:
  std::string file_, item_;
  SourceLoc loc_;
  std::string detail_;
};

// A failed analysis (cannot assemble, singular Jacobian, no convergence). Exit status 1.
class AnalysisError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Bad usage of the command line that is not about a file's content. Exit status 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Writing a result failed (a full disk, a closed pipe, a failed rename). Exit status 1.
class OutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace kinegen::codegen
