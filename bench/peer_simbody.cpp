#include "work_precision.hpp"

namespace kinegen::bench {

std::vector<RunResult> run_simbody(const std::string&, const BenchGrid&, std::string& skipped) {
  skipped = "simbody: skipped: not implemented yet";
  return {};
}

}  // namespace kinegen::bench
