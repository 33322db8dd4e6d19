// --fold-params: parameter values folded into constants at generation give the same numbers as
// the ordinary header with run-time Params (to rounding: folding may combine constants that the
// run-time code multiplies at run time), also with --param overrides; and the folded code does
// not read Params.
#include <algorithm>
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <kinegen/solver.hpp>
#include <random>
#include <sstream>
#include <string>

#include "four_bar.hpp"
#include "four_bar_folded.hpp"
#include "four_bar_folded_overrides.hpp"
#include "offset_slider_crank.hpp"
#include "offset_slider_crank_folded.hpp"
#include "quick_return.hpp"
#include "quick_return_folded.hpp"
#include "slider_crank.hpp"
#include "slider_crank_folded.hpp"
#include "support/run_command.hpp"

namespace {

using namespace kinegen::models;

constexpr double kRelTol = 1e-13;

void require_close(const double* a, const double* b, int n, const char* what) {
  for (int k = 0; k < n; ++k) {
    INFO(what << "[" << k << "]: " << a[k] << " vs " << b[k]);
    REQUIRE(std::abs(a[k] - b[k]) <= kRelTol * std::max(1.0, std::abs(a[k])));
  }
}

// Both models' functions at random configurations near q0.
template <class Plain, class Folded>
void compare(const typename Plain::Params& plain_params) {
  static_assert(Plain::nq == Folded::nq && Plain::nc == Folded::nc &&
                Plain::jac_nnz == Folded::jac_nnz);
  CHECK(Plain::jac_rows == Folded::jac_rows);
  CHECK(Plain::jac_cols == Folded::jac_cols);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const typename Folded::Params folded_params{};
  for (int sample = 0; sample < 20; ++sample) {
    std::array<double, Plain::nq> q, qd;
    for (int k = 0; k < Plain::nq; ++k) {
      q[k] = Plain::q0[k] + 0.3 * u(rng);
      qd[k] = 2 * u(rng);
    }
    const double t = 3 * u(rng);
    std::array<double, Plain::nc> a, b;
    std::array<double, Plain::jac_nnz> ja, jb;
    Plain::phi(q.data(), t, plain_params, a.data());
    Folded::phi(q.data(), t, folded_params, b.data());
    require_close(a.data(), b.data(), Plain::nc, "phi");
    Plain::phi_q(q.data(), t, plain_params, ja.data());
    Folded::phi_q(q.data(), t, folded_params, jb.data());
    require_close(ja.data(), jb.data(), Plain::jac_nnz, "phi_q");
    Plain::nu(q.data(), t, plain_params, a.data());
    Folded::nu(q.data(), t, folded_params, b.data());
    require_close(a.data(), b.data(), Plain::nc, "nu");
    Plain::gamma(q.data(), qd.data(), t, plain_params, a.data());
    Folded::gamma(q.data(), qd.data(), t, folded_params, b.data());
    require_close(a.data(), b.data(), Plain::nc, "gamma");
  }

  // A full crank turn through the solver: the same positions and accelerations.
  kinegen::Solver<Plain> plain(plain_params);
  kinegen::Solver<Folded> folded;
  auto qa = plain.initial_estimate();
  auto qb = folded.initial_estimate();
  typename kinegen::Solver<Plain>::Vector qda, qdda;
  typename kinegen::Solver<Folded>::Vector qdb, qddb;
  for (int k = 0; k <= 90; ++k) {
    const double t = 2 * M_PI * k / 90;
    REQUIRE(plain.position(qa, t));
    REQUIRE(folded.position(qb, t));
    plain.velocity(qa, t, qda);
    folded.velocity(qb, t, qdb);
    plain.acceleration(qa, qda, t, qdda);
    folded.acceleration(qb, qdb, t, qddb);
    REQUIRE((qa - qb).cwiseAbs().maxCoeff() <= 1e-12);
    REQUIRE((qdda - qddb).cwiseAbs().maxCoeff() <=
            1e-10 * std::max(1.0, qdda.cwiseAbs().maxCoeff()));
  }
}

std::string read(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST_CASE("folded parameters give the same numbers as run-time Params", "[fold]") {
  compare<slider_crank, slider_crank_folded>({});
  compare<offset_slider_crank, offset_slider_crank_folded>({});
  compare<four_bar, four_bar_folded>({});
  compare<quick_return, quick_return_folded>({});
}

TEST_CASE("--param overrides are folded too", "[fold]") {
  four_bar::Params p;
  p.a = 1.2;
  p.omega = 2;
  compare<four_bar, four_bar_folded_overrides>(p);
  // The folded header keeps its Params for the same API, with the overridden defaults.
  CHECK(four_bar_folded_overrides::Params{}.a == 1.2);
}

TEST_CASE("folded code does not read Params", "[fold]") {
  // Changing a member has no effect on the folded model ...
  const std::array<double, four_bar::nq> q = four_bar::q0;
  four_bar_folded::Params changed;
  changed.a = 10;
  changed.omega = -3;
  std::array<double, four_bar::nc> a, b;
  four_bar_folded::phi(q.data(), 0.7, four_bar_folded::Params{}, a.data());
  four_bar_folded::phi(q.data(), 0.7, changed, b.data());
  CHECK(a == b);
  // ... and the text has no parameter reads left, while the ordinary header has them.
  const std::string folded = read(KINEGEN_FOLDED_DIR "/four_bar_folded.hpp");
  REQUIRE_FALSE(folded.empty());
  CHECK(folded.find("p.") == std::string::npos);
  CHECK(folded.find("--fold-params") != std::string::npos);
  const std::string plain = read(KINEGEN_SOURCE_DIR "/generated/four_bar.hpp");
  CHECK(plain.find("T(p.a)") != std::string::npos);
}

TEST_CASE("generate: --verbose reports each stage, default only the result, --quiet nothing",
          "[fold][messages]") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "fold_messages";
  fs::create_directories(dir);
  const std::string mech = KINEGEN_SOURCE_DIR "/examples/four_bar.yaml";
  const auto verbose = kinegen::test::run_command(
      {KINEGEN_EXE, "generate", mech, "-o", dir.string(), "--fold-params", "--verbose"});
  REQUIRE(verbose.exit_code == 0);
  for (const char* stage :
       {"kinegen: reading", "kinegen: deriving", "kinegen: folding 7 parameters",
        "kinegen: lowering", "kinegen: emitting", "kinegen: wrote"})
    CHECK(verbose.err.find(stage) != std::string::npos);
  // Not a terminal: no progress lines, just what was written.
  const auto normal =
      kinegen::test::run_command({KINEGEN_EXE, "generate", mech, "-o", dir.string()});
  REQUIRE(normal.exit_code == 0);
  CHECK(normal.err.rfind("kinegen: wrote ", 0) == 0);
  CHECK(std::count(normal.err.begin(), normal.err.end(), '\n') == 1);
  const auto quiet =
      kinegen::test::run_command({KINEGEN_EXE, "--quiet", "generate", mech, "-o", dir.string()});
  CHECK(quiet.exit_code == 0);
  CHECK(quiet.err.empty());
  // Errors still print under --quiet.
  const auto bad = kinegen::test::run_command(
      {KINEGEN_EXE, "generate", mech + ".missing", "-o", dir.string(), "--quiet"});
  CHECK(bad.exit_code == 2);
  CHECK(bad.err.rfind("error: ", 0) == 0);
}
