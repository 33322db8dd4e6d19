// Runs the kinegen binary under test (KINEGEN_EXE, which tests/CMakeLists.txt defines) with
// the given arguments, for end-to-end tests of the command line.
#ifndef KINEGEN_TESTS_SUPPORT_CLI_HPP
#define KINEGEN_TESTS_SUPPORT_CLI_HPP

#include <string>
#include <vector>

#include "support/run_command.hpp"

namespace kinegen::test {

inline CommandResult kinegen_cli(const std::vector<std::string>& args) {
  std::vector<std::string> argv{KINEGEN_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  return run_command(argv);
}

}  // namespace kinegen::test

#endif  // KINEGEN_TESTS_SUPPORT_CLI_HPP
