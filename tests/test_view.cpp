// kinegen view's data (io/view.hpp): which rows a long run keeps, and that they are the file's
// own values. The page itself is tested in headless Chromium (viewer/tests/view.test.mjs).
#include <algorithm>
#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <set>
#include <string>

#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/io/view.hpp"
#include "support/files.hpp"
#include "support/run_command.hpp"

namespace kc = kinegen::codegen;
namespace fs = std::filesystem;

namespace {

// kinegen in a child with 1 GiB of address space and 20 s of CPU: a cost that is not bounded
// ends in bad_alloc (exit 1) or a signal, not in the exit 2 these tests ask for.
kinegen::test::CommandResult run_bounded(const std::vector<std::string>& args,
                                         const fs::path& dir) {
  std::vector<std::string> argv{KINEGEN_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  fs::remove(out);
  kinegen::test::ChildProcess child(argv, "/dev/null", out.string(), err.string(), 20,
                                    rlim_t{1} << 30);
  kinegen::test::CommandResult r;
  r.exit_code = child.wait();
  r.out = kinegen::test::read_text(out);
  r.err = kinegen::test::read_text(err);
  return r;
}

bool one_error_line(const std::string& err) {
  return err.rfind("error: ", 0) == 0 && std::count(err.begin(), err.end(), '\n') == 1;
}

std::size_t kept(std::size_t total, std::size_t stride) {
  std::set<std::size_t> rows;
  for (std::size_t r = 0; r < total; r += stride) rows.insert(r);
  rows.insert(total - 1);
  return rows.size();
}

}  // namespace

TEST_CASE("view: the stride keeps at most max_rows rows, and is the smallest that does",
          "[view]") {
  for (std::size_t total = 1; total < 400; ++total)
    for (std::size_t max_rows = 2; max_rows < 60; ++max_rows) {
      const std::size_t s = kc::decimation_stride(total, max_rows);
      INFO(total << " rows, at most " << max_rows << ": stride " << s);
      REQUIRE(kept(total, s) <= max_rows);
      if (s > 1) REQUIRE(kept(total, s - 1) > max_rows);
    }
  CHECK(kc::decimation_stride(1000000, 200000) == 6);
  CHECK(kc::decimation_stride(100001, 200000) == 1);
}

TEST_CASE("view: a decimated CSV keeps every stride-th row and the last, as written", "[view]") {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "view";
  fs::create_directories(dir);
  const fs::path file = dir / "rows.csv";
  {
    std::ofstream out(file);
    out << std::setprecision(17) << "t, x\r\n";
    for (int r = 0; r < 1001; ++r) out << r << ", " << 0.1 * r << (r % 7 ? "\n" : "\r\n");
  }
  const kc::RunTable run = kc::read_run_csv(file.string(), 100);
  REQUIRE(run.columns == std::vector<std::string>{"t", "x"});
  REQUIRE(run.total_rows == 1001);
  REQUIRE(run.stride == 11);  // ceil(1000 / 99): rows 0, 11, ..., 990 and 1000
  REQUIRE(run.rows() == 92);
  for (std::size_t k = 0; k + 1 < run.rows(); ++k) {
    CHECK(run.values[0][k] == static_cast<double>(11 * k));
    CHECK(run.values[1][k] == 0.1 * static_cast<double>(11 * k));  // 17 digits: the same double
  }
  CHECK(run.values[0].back() == 1000);
  CHECK(run.values[1].back() == 0.1 * 1000);
  std::ofstream(dir / "bad.csv") << "t,x\n0,1\n1,2,3\n";
  REQUIRE_THROWS_WITH(kc::read_run_csv((dir / "bad.csv").string(), 100),
                      Catch::Contains("bad.csv:3: row 1: 3 values where the header has 2"));
}

namespace {

const std::string kFourBar = KINEGEN_SOURCE_DIR "/examples/four_bar.yaml";

// The four-bar's modes JSON as kinegen modes writes it, with `extra` before its closing brace:
// its coordinates (3 bodies), one mode of the crank turning.
std::string four_bar_modes(const std::string& extra = "") {
  return "{\"coordinates\": [\"crank.x\", \"crank.y\", \"crank.phi\", \"coupler.x\", "
         "\"coupler.y\", \"coupler.phi\", \"rocker.x\", \"rocker.y\", \"rocker.phi\"],\n"
         "\"q\": [0, 0, 0, 1, 0, 0.5, 3, 0, 1.5],\n\"frequencies\": [1.5],\n"
         "\"shapes\": [[0, 0, 1, 0, 0, 0, 0, 0, 0]],\n\"damping_ratios\": [NaN], \"t\": null" +
         extra + "}\n";
}

}  // namespace

TEST_CASE("view --modes: the JSON is read with bounded memory and nesting", "[view]") {
  const fs::path dir = kinegen::test::scratch_dir("view", "modes_json");
  const auto model = kc::CompiledModel::from_file(kFourBar, {});
  const auto read = [&](const std::string& name, const std::string& text) {
    kinegen::test::write_text(dir / name, text);
    return kc::read_modes_json((dir / name).string(), *model);
  };
  // What kinegen modes writes (NaN and null in the keys the page reads past) reads back.
  const kc::ModeSet ok = read("ok.json", four_bar_modes());
  CHECK(ok.frequencies == std::vector<double>{1.5});
  CHECK(ok.q[8] == 1.5);
  CHECK(ok.shapes.at(0)[2] == 1);
  // A key that is not a string: the file, its line and the key, as an input error (exit 2),
  // not yaml-cpp's "bad conversion" as an internal error naming the mechanism file.
  for (const auto& [key, shown] : {std::pair<std::string, std::string>{"[1, 2]", "[1, 2]"},
                                   {"{\"a\": 1}", "{\"a\""},
                                   {"3", "3"},
                                   {"q2", "q2"}}) {
    INFO(key);
    REQUIRE_THROWS_WITH(read("key.json", four_bar_modes(",\n" + key + ": 7")),
                        (dir / "key.json").string() + ":6: key " + shown +
                            ": a key must be a string in double quotes (the keys are q, "
                            "frequencies, shapes, ...)");
  }
  // Nesting beyond what a modes JSON has, inside a key the page reads past.
  REQUIRE_THROWS_WITH(
      read("deep.json", four_bar_modes(", \"mass\": " + std::string(9, '[') + std::string(9, ']'))),
      Catch::Contains("deep.json:5: modes: nested deeper than 8 levels"));
  // A key the page reads past is parsed and dropped, however long (within the size bound); what
  // it keeps is bounded by the mechanism's size: here 9 coordinates, (9 + 2)^2 + 8 values.
  std::string zeros = "0";
  for (int k = 0; k < 20000; ++k) zeros += ", 0";
  CHECK(read("long.json", four_bar_modes(", \"mass\": [" + zeros + "]")).q[8] == 1.5);
  std::string shapes = "[0, 0, 1, 0, 0, 0, 0, 0, 0]";
  for (int k = 0; k < 20; ++k) shapes += ", [0, 0, 1, 0, 0, 0, 0, 0, 0]";
  std::string wide = four_bar_modes();
  wide.replace(wide.find("[[0, 0, 1, 0, 0, 0, 0, 0, 0]]"), 29, "[" + shapes + "]");
  REQUIRE_THROWS_WITH(read("wide.json", wide),
                      Catch::Contains("wide.json:4: modes: more than 129 values in its "
                                      "coordinates, q, frequencies and shapes"));
  // More modes than coordinates.
  std::string many = four_bar_modes();
  many.replace(many.find("[1.5]"), 5, "[1, 2, 3, 4, 5, 6, 7, 8, 9, 10]");
  REQUIRE_THROWS_WITH(read("many.json", many),
                      Catch::Contains("many.json:3: frequencies: 10 modes; the mechanism has at "
                                      "most 9 (one per coordinate)"));
}

TEST_CASE(
    "view --modes: a huge or deeply nested JSON and a key that is not a string exit 2 at "
    "once, naming the limit",
    "[view]") {
  if (!kc::viewer_built()) {
    WARN("this build has no viewer: kinegen view --modes is not run");
    return;
  }
  const fs::path dir = kinegen::test::scratch_dir("view", "modes_bounds");
  const std::string page = (dir / "page.html").string();
  const auto view = [&](const std::string& name, const std::string& text) {
    kinegen::test::write_text(dir / name, text);
    return run_bounded({"view", kFourBar, "--modes", (dir / name).string(), "-o", page}, dir);
  };
  // 10 MB of modes (one shape repeated): refused before it is parsed, by its size. The
  // four-bar's 9 coordinates allow 64 KiB + 64 bytes for each of 8 (9 + 1)^2 numbers.
  std::string shapes;
  while (shapes.size() < (10u << 20))
    shapes += std::string(shapes.empty() ? "" : ", ") + "[0, 0, 1, 0, 0, 0, 0, 0, 0]";
  auto r = view("huge.json",
                "{\"q\": [0, 0, 0, 1, 0, 0.5, 3, 0, 1.5], \"frequencies\": [1], "
                "\"shapes\": [" +
                    shapes + "]}");
  INFO(r.err);
  CHECK(r.exit_code == 2);
  CHECK(one_error_line(r.err));
  CHECK(r.err.find("huge.json' is larger than 116736 bytes, the most a modes JSON of " + kFourBar +
                   " (9 coordinates) may be") != std::string::npos);
  // 16 MB of nested brackets: also by its size; 100 KB of them (within the size): by the depth.
  r = view("brackets.json", std::string(16u << 20, '['));
  CHECK(r.exit_code == 2);
  CHECK(one_error_line(r.err));
  CHECK(r.err.find("is larger than 116736 bytes") != std::string::npos);
  r = view("nested.json", std::string(100000, '['));
  CHECK(r.exit_code == 2);
  CHECK(one_error_line(r.err));
  CHECK(r.err.find("nested.json:1: modes: nested deeper than 8 levels") != std::string::npos);
  // A key that is not a string: the JSON file and the key, exit 2.
  r = view("key.json", four_bar_modes(", [1]: 2"));
  CHECK(r.exit_code == 2);
  CHECK(one_error_line(r.err));
  CHECK(r.err.find("error: " + (dir / "key.json").string() +
                   ":5: key [1]: a key must be a string") != std::string::npos);
  CHECK_FALSE(fs::exists(page));
  // What kinegen modes writes is read (the page is written).
  const std::string modes = (dir / "modes.json").string();
  const std::string spring = KINEGEN_SOURCE_DIR "/examples/dynamics/four_bar_spring.yaml";
  r = run_bounded({"modes", spring, "--format", "json", "-o", modes}, dir);
  REQUIRE(r.exit_code == 0);
  r = run_bounded({"view", spring, "--modes", modes, "-o", page}, dir);
  CHECK(r.exit_code == 0);
  CHECK(fs::exists(page));
}
