#include "kinegen/codegen/base/diagnostics.hpp"

namespace kinegen::codegen {

namespace {
std::string format(const std::string& file, const std::string& item, SourceLoc loc,
                   const std::string& message) {
  std::string where = file;
  if (loc.line > 0) where += ":" + std::to_string(loc.line);
  return where + ": " + item + ": " + message;
}
}  // namespace

InputError::InputError(std::string file, std::string item, SourceLoc loc,
                       const std::string& message)
    : std::runtime_error(format(file, item, loc, message)),
      file_(std::move(file)),
      item_(std::move(item)),
      loc_(loc),
      detail_(message) {}

}  // namespace kinegen::codegen
