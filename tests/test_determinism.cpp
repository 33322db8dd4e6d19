// Generated headers are byte-identical from run to run. GiNaC orders operands by hashes that
// mix in addresses, which differ between processes under address-space layout randomization,
// so each generation runs in a process of its own. [release]: the ~400 processes of generate (every
// shipped mechanism, two modes, four runs) take 2.5 minutes under the sanitizers and add nothing
// there; they run in builds without AddressSanitizer only.
#include <algorithm>
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "support/files.hpp"
#include "support/run_command.hpp"

namespace {

namespace fs = std::filesystem;
using kinegen::test::read_text;

constexpr int kRuns = 4;

std::vector<fs::path> shipped_mechanisms() {
  std::vector<fs::path> files;
  for (const char* dir : {"examples", "tests/mechanisms"})
    for (const auto& entry : fs::recursive_directory_iterator(fs::path(KINEGEN_SOURCE_DIR) / dir))
      if (entry.path().extension() == ".yaml") files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

// The address space layout of a process, as far as a child can see it differ: where the
// heap and the libraries start.
std::string layout_of_child() {
  const auto r = kinegen::test::run_command({"/bin/cat", "/proc/self/maps"});
  return r.out;
}

}  // namespace

TEST_CASE("generate writes the same bytes in every process", "[determinism][release]") {
  const auto files = shipped_mechanisms();
  REQUIRE(files.size() >= 6);  // the examples and the test mechanisms
  const fs::path root = fs::path(KINEGEN_TEST_TMP) / "determinism";
  fs::remove_all(root);
  // Also with repeated pieces and parts, whose classes were once ordered by printed keys.
  const std::vector<std::vector<std::string>> modes = {
      {}, {"--roll-min", "2", "--max-function-ops", "50"}};
  for (const auto& file : files)
    for (const auto& mode : modes) {
      INFO(file.string() << (mode.empty() ? "" : " --roll-min 2 --max-function-ops 50"));
      const std::string name = file.stem().string();
      std::string first;
      for (int run = 0; run < kRuns; ++run) {
        const fs::path dir = root / std::to_string(run);
        std::vector<std::string> args = {KINEGEN_EXE, "generate", file.string(), "-o",
                                         dir.string()};
        args.insert(args.end(), mode.begin(), mode.end());
        const auto r = kinegen::test::run_command(args);
        INFO(r.err);
        REQUIRE(r.exit_code == 0);
        const std::string text = read_text(dir / (name + ".hpp"));
        REQUIRE(!text.empty());
        if (run == 0)
          first = text;
        else
          CHECK(text == first);  // a failure here means some order still follows GiNaC's hashes
      }
    }
}

TEST_CASE("processes differ in address space layout, so the test above can see hash orders",
          "[determinism]") {
  // Without randomization every process would get the same hash order and the comparison
  // above could not fail; say so rather than pass quietly.
  const std::string a = layout_of_child(), b = layout_of_child();
  REQUIRE(!a.empty());
  if (a == b) WARN("address space layout randomization is off: determinism is not exercised");
}
