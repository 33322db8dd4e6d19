// Sub-steps (kinegen::substeps, motion.hpp): a step that is refused (its solve failed, or it
// jumped) is taken in halves, so a coarse grid gives its rows where one Newton start per row
// cannot. tests/mechanisms/indexer.yaml (a four-bar whose crank rises harmonically, dwells and
// rises 3-4-5, period 4) over one period in 2, 4 and 8 steps must give the rows of a 16-step
// run at the shared times (to the solver's tolerance), exactly as many rows as asked; without
// sub-steps the same grids fail. A generated Solver with the same substep_halvings takes the
// same sub-steps, bit for bit, and fails the same way without them. A true singularity still
// fails, naming the time where the sub-steps stopped.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <kinegen/block_solver.hpp>
#include <string>
#include <vector>

#include "indexer.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "support/run_command.hpp"

namespace {

namespace kc = kinegen::codegen;

std::string source(const std::string& path) { return std::string(KINEGEN_SOURCE_DIR) + "/" + path; }

std::vector<kc::StateRow> rows_of(const kc::CompiledModel& model, const kc::TimeGrid& grid,
                                  const kc::AnalysisOptions& options = {}) {
  std::vector<kc::StateRow> rows;
  kc::run_analysis(
      model, grid, [&](const kc::StateRow& r) { rows.push_back(r); }, options);
  return rows;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

}  // namespace

TEST_CASE("sub-steps: a coarse grid over the indexer gives the rows of a fine one",
          "[substeps]") {
  const auto model = kc::CompiledModel::from_file(source("tests/mechanisms/indexer.yaml"));
  const auto fine = rows_of(*model, {0, 4, 16});
  REQUIRE(fine.size() == 17);
  for (const int steps : {2, 4, 8}) {
    CAPTURE(steps);
    for (const bool blocks : {true, false}) {
      CAPTURE(blocks);
      kc::AnalysisOptions options;
      options.block_solver = blocks;
      const auto coarse = rows_of(*model, {0, 4, steps}, options);
      REQUIRE(static_cast<int>(coarse.size()) == steps + 1);
      double worst = 0;
      for (int k = 0; k <= steps; ++k) {
        const kc::StateRow& c = coarse[k];
        const kc::StateRow& f = fine[k * (16 / steps)];
        REQUIRE(c.t == f.t);
        for (int i = 0; i < model->nq(); ++i)
          worst = std::max({worst, std::abs(c.q[i] - f.q[i]), std::abs(c.qd[i] - f.qd[i]),
                            std::abs(c.qdd[i] - f.qdd[i]) / 10});
      }
      INFO("largest difference from the 16-step rows " << worst);
      CHECK(worst <= 1e-9);  // both solved to the tolerance 1e-10 (scaled step)
      // Without sub-steps (as before them) the block program, analyze's default, refuses the
      // same grid: one Newton start per row cannot follow (a jump, or a block's determinant
      // changing sign). The dense Newton, damped, happens to follow 8 steps.
      options.substep_halvings = 0;
      if (blocks) CHECK_THROWS_AS(rows_of(*model, {0, 4, steps}, options), kc::AnalysisError);
    }
  }
}

TEST_CASE("sub-steps: the command line writes the rows asked for", "[substeps][cli]") {
  const auto dir = std::filesystem::path(KINEGEN_TEST_TMP) / "substeps";
  std::filesystem::create_directories(dir);
  const std::string csv = (dir / "indexer.csv").string();
  const auto r = kinegen::test::run_command({KINEGEN_EXE, "analyze",
                                             source("tests/mechanisms/indexer.yaml"), "--t0", "0",
                                             "--t1", "4", "--steps", "8", "-o", csv, "-q"});
  INFO(r.err);
  CHECK(r.exit_code == 0);
  CHECK(r.err.empty());
  std::ifstream in(csv);
  int lines = 0;
  for (std::string line; std::getline(in, line);) ++lines;
  CHECK(lines == 1 + 9);
}

TEST_CASE("sub-steps: the generated Solver takes the same sub-steps as analyze, bit for bit",
          "[substeps][same_answers]") {
  using M = kinegen::models::indexer;
  const auto model = kc::CompiledModel::from_file(source("tests/mechanisms/indexer.yaml"));
  for (const int steps : {2, 4, 8}) {
    CAPTURE(steps);
    const kc::TimeGrid grid{0, 4, steps};
    const auto rows = rows_of(*model, grid);
    kinegen::SolverOptions options = kinegen::default_options<double>();
    options.substep_halvings = kinegen::kAnalyzeSubstepHalvings;
    kinegen::Solver<M> solver(M::Params{}, options);
    auto q = solver.initial_estimate();
    decltype(q) qd = decltype(q)::Zero(), qdd = decltype(q)::Zero();
    int differ = 0;
    for (int k = 0; k <= steps; ++k) {
      REQUIRE(solver.step(grid.at(k), q, qd, qdd));
      for (int c = 0; c < M::nq; ++c)
        differ += !same_bits(q[c], rows[k].q[c]) + !same_bits(qd[c], rows[k].qd[c]) +
                  !same_bits(qdd[c], rows[k].qdd[c]);
    }
    CHECK(differ == 0);
    // Off (the default, a fixed cost per step): the step is refused, and leaves its history.
    kinegen::Solver<M> plain;
    q = plain.initial_estimate();
    REQUIRE(plain.step(0, q, qd, qdd));
    bool failed = false;
    for (int k = 1; k <= steps && !failed; ++k) {
      const auto r = plain.step(grid.at(k), q, qd, qdd);
      if (!r) {
        failed = true;
        CHECK(plain.failed_time() == grid.at(k));
        CHECK(std::isnan(qd[0]));
      }
    }
    CHECK(failed);
  }
}

TEST_CASE("sub-steps: a true singularity still fails, naming where the sub-steps stopped",
          "[substeps][stability]") {
  // rocker_overdriven.yaml: the rocker is driven past its upper limit acos(-0.6) = 2.2143 rad,
  // reached at t = 0.70953 (phi = 1.5048 + t); with 20 steps the grid has 0.70 and 0.75.
  const auto model =
      kc::CompiledModel::from_file(source("tests/stability/rocker_overdriven.yaml"));
  std::vector<kc::StateRow> rows;
  try {
    kc::run_analysis(*model, {0, 1, 20}, [&](const kc::StateRow& r) { rows.push_back(r); });
    FAIL("no error");
  } catch (const kc::AnalysisError& e) {
    const std::string what = e.what();
    INFO(what);
    const auto at = what.find("failed at t = ");
    REQUIRE(at != std::string::npos);
    const double t = std::stod(what.substr(at + 14));
    const double limit = std::acos(-0.6) - 1.5048072742452929;
    CHECK(t >= limit - 0.05 / 4096);
    CHECK(t <= limit + 0.05 / 4096 * 2);  // within two of the shortest sub-steps
    CHECK(what.find("(in sub-steps of the step from t = 0.69999999999999996 to t = 0.75, down to "
                    "1/4096 of it)") != std::string::npos);
  }
  CHECK(rows.size() == 15);  // t = 0 .. 0.70, as asked, nothing of the sub-steps
}
