// Tolerance analysis (kinegen tolerance): the linear figures from the exact sensitivities
// against Monte Carlo, and hostile input.
//  - For small tolerances the deviation is linear in the parameters up to O(delta^2), so the
//    linear worst case bounds every sampled deviation (to 1 % here, for delta ~ 1e-4 of
//    lengths ~ 1, the quadratic term is ~1e-4 relative).
//  - Each parameter is uniform in [p - delta, p + delta] (standard deviation delta / sqrt 3),
//    so the deviation's standard deviation is rss / sqrt(3). The sample standard deviation of
//    N draws has a relative standard error of at most 1 / sqrt(2N) (kurtosis <= 3): with
//    N = 2000, 1.6 %; the bound is 5 of those, 7.9 %.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "kinegen/codegen/analysis/tolerance.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "support/run_command.hpp"

namespace {
namespace cg = kinegen::codegen;
const std::string kFourBar = std::string(KINEGEN_SOURCE_DIR) + "/examples/four_bar.yaml";
}  // namespace

TEST_CASE("linear worst case bounds the Monte Carlo spread; rss ~ sqrt(3) mc std", "[tolerance]") {
  const auto model = cg::CompiledModel::from_file(kFourBar);
  cg::ToleranceOptions options;
  options.tolerances =
      cg::parse_tolerances({"a=1e-4", "b=2e-4", "c=1e-4", "d=1.5e-4", "px=2e-4", "py=1e-4"});
  options.grid = {0, 2 * std::acos(-1.0), 24};
  options.monte_carlo = 2000;
  options.seed = 7;
  const auto r = cg::tolerance_analysis(*model, options);
  REQUIRE(r.samples == 2000);
  REQUIRE(r.t.size() == 25);
  REQUIRE(r.quantities.size() == 9 + 6);
  const double sampling = 5 / std::sqrt(2.0 * options.monte_carlo);
  int compared = 0;
  for (std::size_t row = 0; row < r.t.size(); ++row)
    for (std::size_t q = 0; q < r.quantities.size(); ++q) {
      INFO(r.quantities[q] << " at t = " << r.t[row] << ": worst " << r.worst[row][q] << ", rss "
                           << r.rss[row][q] << ", mc spread " << r.mc_spread[row][q] << ", mc std "
                           << r.mc_std[row][q]);
      REQUIRE(r.mc_spread[row][q] <= 1.01 * r.worst[row][q] + 1e-13);
      REQUIRE(r.rss[row][q] <= r.worst[row][q] + 1e-18);
      REQUIRE(std::abs(std::sqrt(3.0) * r.mc_std[row][q] - r.rss[row][q]) <=
              sampling * r.rss[row][q] + 1e-13);
      if (r.rss[row][q] > 1e-6) ++compared;
    }
  CHECK(compared > 200);  // most quantities move (the crank's x, y, phi and O4's y do not)
}

TEST_CASE("tolerance without Monte Carlo: the figures follow from the sensitivities",
          "[tolerance]") {
  // One parameter: worst case = rss = |dC/dp| delta. The coupler's origin is the crank tip
  // A = a [cos t, sin t] (omega = 1), so d(A.x)/da = cos t.
  const auto model = cg::CompiledModel::from_file(kFourBar);
  cg::ToleranceOptions options;
  options.tolerances = cg::parse_tolerances({"a=0.01"});
  options.grid = {0, 3, 6};
  const auto r = cg::tolerance_analysis(*model, options);
  CHECK(r.samples == 0);
  CHECK(r.mc_std.empty());
  const std::size_t ax = 9;  // crank, coupler, rocker (3 each), then A.x
  REQUIRE(r.quantities[ax] == "A.x");
  for (std::size_t row = 0; row < r.t.size(); ++row) {
    CHECK(std::abs(r.worst[row][ax] - 0.01 * std::abs(std::cos(r.t[row]))) <= 1e-15);
    CHECK(r.rss[row][ax] == Approx(r.worst[row][ax]).margin(1e-18));
  }
  const std::string csv = cg::tolerance_csv(r);
  CHECK(csv.rfind("t,crank.x.worst,crank.x.rss,crank.y.worst", 0) == 0);
}

TEST_CASE("tolerance covers the extra coordinates", "[tolerance]") {
  // The disc cam's roller centre stays on the y axis, so its pitch angle u equals the cam
  // angle t whatever the base radius: du/dRb = 0; the follower rides at y = Rb + r + s(t):
  // d(follower.y)/dRb = 1, and so does a point R on the follower. Before u was listed, the
  // figures ran one quantity short and the Monte Carlo read past its rows (a different garbage
  // number on every run).
  std::ifstream in(std::string(KINEGEN_SOURCE_DIR) + "/examples/cams/disc_cam.yaml");
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml = text.str();
  yaml.replace(yaml.find("outputs:"), 8,
               "points:\n  - {name: R, body: follower, s: [0.002, 0.01]}\noutputs:");
  const auto model = cg::CompiledModel::from_mechanism(cg::parse_mechanism(yaml, "cam.yaml"));
  cg::ToleranceOptions options;
  options.tolerances = cg::parse_tolerances({"Rb=1e-4"});
  options.grid = {0, 2 * std::acos(-1.0), 12};
  options.monte_carlo = 20;
  options.seed = 3;
  const auto r = cg::tolerance_analysis(*model, options);
  REQUIRE(r.quantities.size() == 3 * 2 + 1 + 2);
  const std::size_t follower_y = 4, u = 6, rx = 7, ry = 8;
  REQUIRE(r.quantities[follower_y] == "follower.y");
  REQUIRE(r.quantities[u] == "u");
  REQUIRE(r.quantities[rx] == "R.x");
  REQUIRE(r.quantities[ry] == "R.y");
  for (std::size_t row = 0; row < r.t.size(); ++row) {
    INFO("t = " << r.t[row]);
    CHECK(std::abs(r.worst[row][follower_y] - 1e-4) <= 1e-15);
    CHECK(std::abs(r.worst[row][ry] - 1e-4) <= 1e-15);
    CHECK(r.worst[row][rx] <= 1e-15);  // the follower does not turn or move sideways
    CHECK(r.worst[row][u] <= 1e-15);
    CHECK(r.mc_spread[row][u] <= 1e-12);
    CHECK(r.mc_spread[row][follower_y] <= 1e-4 * (1 + 1e-9));
    CHECK(r.mc_spread[row][follower_y] >= 0.5e-4);  // 20 uniform draws: P(all < 1/2) = 2^-20
    for (std::size_t q = 0; q < r.quantities.size(); ++q) CHECK(std::isfinite(r.mc_std[row][q]));
  }
}

TEST_CASE("tolerance passes the nominal analysis' warnings on", "[tolerance]") {
  // A redundant (consistent) model is analyzed with a warning, in tolerance as in analyze.
  std::ifstream in(std::string(KINEGEN_SOURCE_DIR) + "/tests/stability/double_parallelogram.yaml");
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml = text.str();
  yaml.replace(yaml.find("bodies:"), 7, "parameters:\n  w: 1\nbodies:");
  yaml.replace(yaml.find("f: \"t\""), 6, "f: \"w*t\"");
  const auto model = cg::CompiledModel::from_mechanism(cg::parse_mechanism(yaml, "dp.yaml"));
  cg::ToleranceOptions options;
  options.tolerances = cg::parse_tolerances({"w=1e-3"});
  options.grid = {0.2, 1, 4};
  std::vector<std::string> warnings;
  options.warn = [&](const std::string& w) { warnings.push_back(w); };
  const auto r = cg::tolerance_analysis(*model, options);
  REQUIRE(r.t.size() == 5);
  REQUIRE_FALSE(warnings.empty());
  CHECK(warnings[0].find("redundant") != std::string::npos);
}

TEST_CASE("tolerance: hostile input", "[tolerance]") {
  SECTION("parse_tolerances") {
    for (const char* bad :
         {"a=-1e-3", "a=nan", "a=inf", "a=1e999", "a=abc", "a=", "=1", "a", "a=1e-3x"})
      CHECK_THROWS_AS(cg::parse_tolerances({bad}), cg::UsageError);
    CHECK_THROWS_AS(cg::parse_tolerances({"a=1", "a=2"}), cg::UsageError);
    CHECK(cg::parse_tolerances({"a=0"})[0].delta == 0.0);  // a zero tolerance is valid
  }
  SECTION("library") {
    const auto model = cg::CompiledModel::from_file(kFourBar);
    cg::ToleranceOptions options;
    options.grid = {0, 1, 2};
    CHECK_THROWS_AS(cg::tolerance_analysis(*model, options), cg::UsageError);  // no --tol
    options.tolerances = {{"nope", 1e-3}};
    CHECK_THROWS_WITH(cg::tolerance_analysis(*model, options),
                      Catch::Contains("--tol: the mechanism has no parameter 'nope'"));
    options.tolerances = {{"a", 1e-3}};
    options.monte_carlo = 1;
    CHECK_THROWS_AS(cg::tolerance_analysis(*model, options), cg::UsageError);
  }
  SECTION("command line: exit 2, one error line, no output file") {
    const std::string exe = KINEGEN_EXE;
    const std::string out = std::string(KINEGEN_TEST_TMP) + "/tolerance_hostile.csv";
    std::filesystem::create_directories(KINEGEN_TEST_TMP);
    std::filesystem::remove(out);
    for (const std::vector<std::string>& extra : {std::vector<std::string>{"--tol", "nope=1e-3"},
                                                  {"--tol", "a=-1e-3"},
                                                  {"--tol", "a=nan"},
                                                  {"--tol", "a=1e-3", "--monte-carlo", "0"},
                                                  {"--tol", "a=1e-3", "--monte-carlo", "1"}}) {
      std::vector<std::string> args = {exe, "tolerance", kFourBar, "--t0", "0", "--t1",
                                       "1", "--steps",   "2",      "-o",   out};
      args.insert(args.end(), extra.begin(), extra.end());
      const auto r = kinegen::test::run_command(args);
      INFO(extra[1] << ": " << r.err);
      CHECK(r.exit_code == 2);
      CHECK(r.err.rfind("error: ", 0) == 0);
      CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
      CHECK_FALSE(std::filesystem::exists(out));
    }
  }
  SECTION("a sample that does not assemble fails the run (exit 1), naming the sample") {
    // l = 2 +- 1.2 draws rods shorter than the crank (1): those cannot turn through t = 3.
    const std::string exe = KINEGEN_EXE;
    const std::string mech = std::string(KINEGEN_SOURCE_DIR) + "/examples/slider_crank.yaml";
    const auto r =
        kinegen::test::run_command({exe, "tolerance", mech, "--t0", "0", "--t1", "3", "--steps",
                                    "30", "--tol", "l=1.2", "--monte-carlo", "50"});
    CHECK(r.exit_code == 1);
    CHECK(r.err.rfind("error: " + mech + ": Monte Carlo sample ", 0) == 0);
    CHECK(r.err.find("(l = ") != std::string::npos);
  }
  SECTION("command line: a good run writes the per-row CSV") {
    const std::string exe = KINEGEN_EXE;
    const std::string out = std::string(KINEGEN_TEST_TMP) + "/tolerance_good.csv";
    std::filesystem::create_directories(KINEGEN_TEST_TMP);
    const auto r = kinegen::test::run_command({exe, "tolerance", kFourBar, "--t0", "0", "--t1", "1",
                                               "--steps", "4", "--tol", "a=1e-3", "--tol",
                                               "px=1e-3", "--monte-carlo", "10", "-o", out});
    CHECK(r.exit_code == 0);
    CHECK(r.out.find("P.x") != std::string::npos);
    std::ifstream in(out);
    std::stringstream text;
    text << in.rdbuf();
    const std::string csv = text.str();
    CHECK(std::count(csv.begin(), csv.end(), '\n') == 6);  // header + 5 rows
    CHECK(csv.find("P.y.mc_std") != std::string::npos);
  }
}
