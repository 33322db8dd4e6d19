// kinegen view's data (io/view.hpp): which rows a long run keeps, and that they are the file's
// own values. The page itself is tested in headless Chromium (viewer/tests/view.test.mjs).
#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <set>
#include <string>

#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/io/view.hpp"

namespace kc = kinegen::codegen;
namespace fs = std::filesystem;

namespace {

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
