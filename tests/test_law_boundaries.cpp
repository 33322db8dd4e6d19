// Motion laws exactly at their boundaries (amended in version 3): a law is its formula
// on [0, 1), so a value at 0 or 1 is the limit from the right, as for a driver's pieces.
// tests/mechanisms/harmonic_return.yaml repeats a harmonic rise and its return every 2 s, a
// motion smooth everywhere, h (1 - cos(pi t)) / 2; on a grid that lands on every boundary the
// analysis, the generated header and the 40-digit reference must give its closed form there
// (acceleration +-h pi^2 / 2), where clamping at 0 gave 0. Also: each arithmetic's kernel at 0
// (double, float, the complex step, CLN, GiNaC's exact value), and kinegen check at boundaries.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <kinegen/block_solver.hpp>
#include <kinegen/kernels/motion_law.hpp>
#include <string>
#include <vector>

#include "harmonic_return.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/check.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace {

namespace cg = kinegen::codegen;
namespace kk = kinegen::kernels;

constexpr double kPi = 3.14159265358979323846;
constexpr double kH = 0.8;  // the file's h

std::string mechanism_path() {
  return std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/harmonic_return.yaml";
}

// The closed form of both cranks' angles at t: q, qd, qdd of rise_return (phi is q[2]) and
// one_shot (q[5]). rise_return: h (1 - cos(pi t)) / 2 for every t. one_shot: the same on
// [0, 2), 0 outside (a time at 2 takes the dwell after it, the limit from the right).
struct Closed {
  double q[6] = {}, qd[6] = {}, qdd[6] = {};
};

Closed closed_form(double t) {
  Closed c;
  const double f = kH * (1 - std::cos(kPi * t)) / 2, v = kH * kPi / 2 * std::sin(kPi * t),
               a = kH * kPi * kPi / 2 * std::cos(kPi * t);
  c.q[2] = f, c.qd[2] = v, c.qdd[2] = a;
  c.q[3] = 2;
  if (t >= 0 && t < 2) c.q[5] = f, c.qd[5] = v, c.qdd[5] = a;
  return c;
}

// t from 0 to 6 in steps of 1/4 (exact in binary): every boundary (t = 1, 2, ... 6) is a row.
const cg::TimeGrid kGrid{0, 6, 24};

// The largest error over a run against the closed form, for positions and for each rate
// relative to its largest magnitude (h pi / 2, h pi^2 / 2).
struct Errors {
  double q = 0, qd = 0, qdd = 0;
  double at_boundaries = 0;  // the accelerations' error at integer t alone
  template <class V>
  void add(double t, const V& q_, const V& qd_, const V& qdd_) {
    const Closed c = closed_form(t);
    for (int k = 0; k < 6; ++k) {
      q = std::max(q, std::abs(double(q_[k]) - c.q[k]));
      qd = std::max(qd, std::abs(double(qd_[k]) - c.qd[k]) / (kH * kPi / 2));
      const double e = std::abs(double(qdd_[k]) - c.qdd[k]) / (kH * kPi * kPi / 2);
      qdd = std::max(qdd, e);
      if (t == std::floor(t)) at_boundaries = std::max(at_boundaries, e);
    }
  }
};

}  // namespace

TEST_CASE("law boundaries: each arithmetic's law at 0 is its formula's, at 1 the clamp",
          "[law_boundaries]") {
  // d^n/dx^n at 0 of cycloidal, harmonic, poly345, poly4567, n = 0..4, from the formulas:
  // cycloidal''' = (2 pi)^2 cos(2 pi x); harmonic'' = pi^2/2 cos(pi x), harmonic'''' =
  // -pi^4/2 cos(pi x); poly345''' = 60 - 360 x + 360 x^2; poly4567'''' = 35 * 24 at 0.
  const double want[4][5] = {{0, 0, 0, 4 * kPi * kPi, 0},
                             {0, 0, kPi * kPi / 2, 0, -std::pow(kPi, 4) / 2},
                             {0, 0, 0, 60, -360},
                             {0, 0, 0, 0, 840}};
  for (int law = 0; law < 4; ++law)
    for (int n = 0; n <= 4; ++n) {
      CAPTURE(law, n);
      const double scale = std::max(1.0, std::abs(want[law][n]));
      CHECK(std::abs(kk::motion_law(law, n, 0.0) - want[law][n]) <= 4e-16 * scale);
      CHECK(std::abs(kk::motion_law(law, n, -0.0) - want[law][n]) <= 4e-16 * scale);
      CHECK(std::abs(double(kk::motion_law(law, n, 0.0f)) - want[law][n]) <= 4e-7 * scale);
      // Just below 0 and at 1 and beyond: clamped.
      CHECK(kk::motion_law(law, n, -1e-300) == 0);
      CHECK(kk::motion_law(law, n, 1.0) == (n == 0 ? 1 : 0));
      CHECK(kk::motion_law(law, n, 1.5) == (n == 0 ? 1 : 0));
      // The complex step at 0 branches on the real part: the derivative from the right.
      if (n < 4) {
        const double hs = 1e-30;
        const double d = kk::motion_law(law, n, std::complex<double>(0, hs)).imag() / hs;
        CHECK(std::abs(d - want[law][n + 1]) <= 4e-16 * std::max(1.0, std::abs(want[law][n + 1])));
      }
      // CLN at 40 digits, at an exact 0 and at a 40-digit float 0.
      const GiNaC::numeric exact = cg::motion_law_high_precision(law, n, 0);
      CHECK(std::abs(exact.to_double() - want[law][n]) <= 4e-16 * scale);
      {
        const cg::DigitsGuard digits(40);
        const GiNaC::ex v = GiNaC::evalf(cg::kinegen_law(law, n, GiNaC::numeric(0)));
        REQUIRE(GiNaC::is_a<GiNaC::numeric>(v));
        CHECK(std::abs(GiNaC::ex_to<GiNaC::numeric>(v).to_double() - want[law][n]) <=
              4e-16 * scale);
      }
      // NaN stays NaN.
      CHECK(std::isnan(kk::motion_law(law, n, std::nan(""))));
    }
  // GiNaC keeps the value at an exact 0 exact: harmonic''(0) = Pi^2 / 2.
  CHECK(GiNaC::ex(cg::kinegen_law(kk::kHarmonic, 2, 0)).is_equal(GiNaC::pow(GiNaC::Pi, 2) / 2));
  CHECK(GiNaC::ex(cg::kinegen_law(kk::kCycloidal, 3, 0)).is_equal(4 * GiNaC::pow(GiNaC::Pi, 2)));
  CHECK(GiNaC::ex(cg::kinegen_law(kk::kPoly345, 3, 0)).is_equal(60));
}

TEST_CASE("law boundaries: analyze gives a repeated harmonic rise-return's accelerations on "
          "every boundary",
          "[law_boundaries]") {
  const auto model = cg::CompiledModel::from_file(mechanism_path());
  // Smooth at every boundary and seam: no warning.
  CHECK(model->symbolic().warnings.empty());
  for (const bool blocks : {true, false}) {
    CAPTURE(blocks);
    cg::AnalysisOptions options;
    options.block_solver = blocks;
    Errors e;
    int rows = 0;
    cg::run_analysis(
        *model, kGrid,
        [&](const cg::StateRow& r) {
          e.add(r.t, r.q, r.qd, r.qdd);
          ++rows;
          if (r.t == 1 || r.t == 3 || r.t == 5) {  // the return's start: -h pi^2 / 2
            CHECK(r.qdd[2] == Approx(-kH * kPi * kPi / 2).epsilon(1e-14));
            CHECK(r.qdd[5] == Approx(r.t == 1 ? -kH * kPi * kPi / 2 : 0).epsilon(1e-14));
          }
          if (r.t == 0 || r.t == 2 || r.t == 4 || r.t == 6)  // the rise's start
            CHECK(r.qdd[2] == Approx(kH * kPi * kPi / 2).epsilon(1e-14));
        },
        options);
    CHECK(rows == 25);
    INFO("errors: q " << e.q << ", qd " << e.qd << ", qdd " << e.qdd << " (at the boundaries "
                      << e.at_boundaries << ")");
    // The closed form in double rounds pi t (t up to 6): a few 1e-16; at the boundaries the
    // laws' values at 0 are exact to rounding.
    CHECK(e.q <= 1e-14);
    CHECK(e.qd <= 1e-14);
    CHECK(e.qdd <= 1e-14);
    CHECK(e.at_boundaries <= 1e-15);
  }
}

TEMPLATE_TEST_CASE("law boundaries: the generated header steps through every boundary",
                   "[law_boundaries]", double, float) {
  using M = kinegen::models::harmonic_return;
  using T = TestType;
  kinegen::Solver<M, T> solver;
  auto q = solver.initial_estimate();
  decltype(q) qd, qdd;
  Errors e;
  for (int k = 0; k <= kGrid.steps; ++k) {
    const double t = kGrid.at(k);  // exact in float too
    CAPTURE(t);
    REQUIRE(solver.step(T(t), q, qd, qdd));
    e.add(t, q, qd, qdd);
  }
  const double bound = sizeof(T) == 4 ? 1e-6 : 1e-14;
  INFO("errors: q " << e.q << ", qd " << e.qd << ", qdd " << e.qdd << " (at the boundaries "
                    << e.at_boundaries << ")");
  CHECK(e.q <= bound);
  CHECK(e.qd <= bound);
  CHECK(e.qdd <= bound);
  CHECK(e.at_boundaries <= (sizeof(T) == 4 ? bound : 1e-15));
}

TEST_CASE("law boundaries: the 40-digit reference agrees with the closed form on every boundary",
          "[law_boundaries]") {
  const auto model = cg::CompiledModel::from_file(mechanism_path());
  Errors e;
  int rows = 0;
  cg::run_reference_analysis(*model, kGrid, 40, [&](const cg::StateRow& r) {
    e.add(r.t, r.q, r.qd, r.qdd);
    ++rows;
  });
  CHECK(rows == 25);
  INFO("errors: q " << e.q << ", qd " << e.qd << ", qdd " << e.qdd << " (at the boundaries "
                    << e.at_boundaries << ")");
  // The closed form here is in double: a few ulps of pi t.
  CHECK(e.q <= 1e-14);
  CHECK(e.qd <= 1e-14);
  CHECK(e.qdd <= 1e-14);
  CHECK(e.at_boundaries <= 1e-15);
}

TEST_CASE("law boundaries: kinegen check's derivatives hold on the boundaries",
          "[law_boundaries]") {
  const auto model = cg::CompiledModel::from_file(mechanism_path());
  for (const double t : {0.0, 1.0, 3.0}) {
    cg::CheckOptions options;
    options.t = t;
    options.samples = 2;
    for (const auto& row : cg::check_derivatives(*model, options)) {
      CAPTURE(t, row.block, row.method, row.max_rel, row.bound);
      CHECK(row.ok());
    }
  }
}
