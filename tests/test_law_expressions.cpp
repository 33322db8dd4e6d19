// The built-in motion laws as functions of the expression language, on
// tests/mechanisms/dwell_slider_crank.yaml (a law in a driver, in an expression joint's
// coordinate and in a torque): the analysis against the laws' formulas written out here, on a
// grid that lands exactly on every kink; the 40-digit reference against the double analysis;
// the generated header in double and float; the complex step through the laws; the laws in
// GiNaC (derivative, exact values); and a wrong argument count as an input error.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <filesystem>
#include <fstream>
#include <kinegen/solver.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "dwell_slider_crank.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/check.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"
#include "support/run_command.hpp"

namespace {

namespace cg = kinegen::codegen;
namespace fs = std::filesystem;

constexpr double kPi = 3.14159265358979323846;
// The file's parameters.
constexpr double kR = 1.0, kL = 3.0, kH = 0.5, kTau = 2.0;

const std::string& mechanism_path() {
  static const std::string path =
      std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/dwell_slider_crank.yaml";
  return path;
}

// A law and its first two derivatives at x, as the spec writes them, clamped outside (0, 1).
struct Law3 {
  double f, d1, d2;
};

Law3 poly345(double x) {
  if (x <= 0) return {0, 0, 0};
  if (x >= 1) return {1, 0, 0};
  return {10 * std::pow(x, 3) - 15 * std::pow(x, 4) + 6 * std::pow(x, 5),
          30 * x * x - 60 * std::pow(x, 3) + 30 * std::pow(x, 4),
          60 * x - 180 * x * x + 120 * std::pow(x, 3)};
}

Law3 poly4567(double x) {
  if (x <= 0) return {0, 0, 0};
  if (x >= 1) return {1, 0, 0};
  return {35 * std::pow(x, 4) - 84 * std::pow(x, 5) + 70 * std::pow(x, 6) - 20 * std::pow(x, 7),
          140 * std::pow(x, 3) - 420 * std::pow(x, 4) + 420 * std::pow(x, 5) - 140 * std::pow(x, 6),
          420 * x * x - 1680 * std::pow(x, 3) + 2100 * std::pow(x, 4) - 840 * std::pow(x, 5)};
}

Law3 cycloidal(double x) {
  if (x <= 0) return {0, 0, 0};
  if (x >= 1) return {1, 0, 0};
  return {x - std::sin(2 * kPi * x) / (2 * kPi), 1 - std::cos(2 * kPi * x),
          2 * kPi * std::sin(2 * kPi * x)};
}

double harmonic(double x) {
  if (x <= 0) return 0;
  if (x >= 1) return 1;
  return (1 - std::cos(kPi * x)) / 2;
}

// The closed form of the mechanism at t: q, qd, qdd of crank, slider, follower (x, y, phi each).
struct Closed {
  double q[9] = {}, qd[9] = {}, qdd[9] = {};
};

Closed closed_form(double t) {
  Closed c;
  // Crank: pi/2 poly345(t/2) + pi/2 poly4567(t - 3).
  const Law3 a = poly345(t / 2), b = poly4567(t - 3);
  const double phi = kPi / 2 * a.f + kPi / 2 * b.f;
  const double w = kPi / 4 * a.d1 + kPi / 2 * b.d1;
  const double al = kPi / 8 * a.d2 + kPi / 2 * b.d2;
  c.q[2] = phi, c.qd[2] = w, c.qdd[2] = al;
  // Slider: x = g(phi) = r cos(phi) + sqrt(l^2 - r^2 sin(phi)^2).
  const double s = std::sin(phi), co = std::cos(phi);
  const double root = std::sqrt(kL * kL - kR * kR * s * s);
  const double g = kR * co + root;
  const double g1 = -kR * s - kR * kR * s * co / root;
  const double g2 = -kR * co - kR * kR * (co * co - s * s) / root -
                    std::pow(kR, 4) * s * s * co * co / std::pow(root, 3);
  c.q[3] = g, c.qd[3] = g1 * w, c.qdd[3] = g2 * w * w + g1 * al;
  // Follower: x = 5, y = h cycloidal(2 phi / pi).
  const Law3 y = cycloidal(2 * phi / kPi);
  c.q[6] = 5;
  c.q[7] = kH * y.f;
  c.qd[7] = kH * y.d1 * (2 / kPi) * w;
  c.qdd[7] = kH * (y.d2 * (2 / kPi) * w * (2 / kPi) * w + y.d1 * (2 / kPi) * al);
  return c;
}

// t from -1 to 5 in steps of 1/4 (exact in binary): every kink (t = 0, 2, 3, 4) is a row.
const cg::TimeGrid kGrid{-1, 5, 24};

std::vector<cg::StateRow> analysis_rows(const cg::CompiledModel& model) {
  std::vector<cg::StateRow> rows;
  cg::run_analysis(model, kGrid, [&](const cg::StateRow& r) { rows.push_back(r); });
  return rows;
}

// Largest error over a run relative to the largest closed-form magnitude of the same quantity.
struct Worst {
  double err = 0, scale = 0;
  void add(double got, double want) {
    err = std::max(err, std::abs(got - want));
    scale = std::max(scale, std::abs(want));
  }
  double relative() const { return err / std::max(scale, 1e-300); }
};

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

TEST_CASE("laws: dwell-rise-dwell slider-crank against the laws' formulas, exact at the kinks",
          "[laws]") {
  const auto model = cg::CompiledModel::from_file(mechanism_path());
  const auto rows = analysis_rows(*model);
  REQUIRE(rows.size() == 25);
  Worst q, qd, qdd;
  for (const auto& row : rows) {
    CAPTURE(row.t);
    const Closed c = closed_form(row.t);
    for (int k = 0; k < 9; ++k) {
      REQUIRE(std::isfinite(row.q[k]));
      REQUIRE(std::isfinite(row.qd[k]));
      REQUIRE(std::isfinite(row.qdd[k]));
      q.add(row.q[k], c.q[k]);
      qd.add(row.qd[k], c.qd[k]);
      qdd.add(row.qdd[k], c.qdd[k]);
    }
    // The dwells and the kinks: the clamped values exactly (0, pi/2, pi as doubles), rest
    // exactly, and the follower exactly at h once the crank is past pi/2.
    if (row.t <= 0 || (row.t >= 2 && row.t <= 3) || row.t >= 4) {
      const double phi = row.t <= 0 ? 0 : row.t <= 3 ? kPi / 2 : kPi;
      CHECK(row.q[2] == phi);
      CHECK(row.qd[2] == 0);
      CHECK(row.qdd[2] == 0);
      CHECK(row.q[7] == (row.t <= 0 ? 0 : kH));
      CHECK(row.qd[7] == 0);
      CHECK(row.qdd[7] == 0);
    }
  }
  INFO("relative errors: q " << q.relative() << ", qd " << qd.relative() << ", qdd "
                             << qdd.relative());
  CHECK(q.relative() < 1e-14);
  CHECK(qd.relative() < 1e-14);
  CHECK(qdd.relative() < 1e-13);
}

TEST_CASE("laws: the 40-digit reference agrees with the double analysis", "[laws]") {
  const auto model = cg::CompiledModel::from_file(mechanism_path());
  const auto rows = analysis_rows(*model);
  std::vector<cg::StateRow> ref;
  cg::run_reference_analysis(*model, kGrid, 40, [&](const cg::StateRow& r) { ref.push_back(r); });
  REQUIRE(ref.size() == rows.size());
  Worst q, qd, qdd, exact;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Closed c = closed_form(rows[i].t);
    for (int k = 0; k < 9; ++k) {
      q.add(rows[i].q[k], ref[i].q[k]);
      qd.add(rows[i].qd[k], ref[i].qd[k]);
      qdd.add(rows[i].qdd[k], ref[i].qdd[k]);
      exact.add(ref[i].qdd[k], c.qdd[k]);
    }
    // The reference's clamped rows are exact too.
    if (rows[i].t >= 2 && rows[i].t <= 3) {
      CHECK(ref[i].q[2] == kPi / 2);
      CHECK(ref[i].qd[2] == 0);
      CHECK(ref[i].qdd[2] == 0);
    }
  }
  INFO("double vs reference: q " << q.relative() << ", qd " << qd.relative() << ", qdd "
                                 << qdd.relative() << "; reference qdd vs formulas "
                                 << exact.relative());
  CHECK(q.relative() < 1e-14);
  CHECK(qd.relative() < 1e-14);
  CHECK(qdd.relative() < 1e-13);
  CHECK(exact.relative() < 1e-13);  // the formulas here are in double
}

TEMPLATE_TEST_CASE("laws: the generated header agrees with the analysis", "[laws]", double, float) {
  using M = kinegen::models::dwell_slider_crank;
  using T = TestType;
  const auto model = cg::CompiledModel::from_file(mechanism_path());
  const auto rows = analysis_rows(*model);
  kinegen::Solver<M, T> solver;
  auto q = solver.initial_estimate();
  decltype(q) qd, qdd;
  Worst eq, eqd, eqdd;
  for (const auto& row : rows) {
    CAPTURE(row.t);
    const T t = T(row.t);  // exact in float too
    REQUIRE(solver.position(q, t));
    REQUIRE(solver.velocity(q, t, qd));
    REQUIRE(solver.acceleration(q, qd, t, qdd));
    for (int k = 0; k < M::nq; ++k) {
      REQUIRE(std::isfinite(double(qdd[k])));
      eq.add(double(q[k]), row.q[k]);
      eqd.add(double(qd[k]), row.qd[k]);
      eqdd.add(double(qdd[k]), row.qdd[k]);
    }
    if (row.t >= 2 && row.t <= 3) {  // clamped: exact in either type
      CHECK(q[2] == T(kPi / 2));
      CHECK(qd[2] == T(0));
      CHECK(qdd[2] == T(0));
    }
  }
  const double bound = sizeof(T) == 4 ? 1e-6 : 1e-14;  // seen: 7e-8 and 3e-16
  INFO("relative to the analysis: q " << eq.relative() << ", qd " << eqd.relative() << ", qdd "
                                      << eqdd.relative());
  CHECK(eq.relative() < bound);
  CHECK(eqd.relative() < bound);
  CHECK(eqdd.relative() < 10 * bound);
  // The header carries the motion_law kernel unchanged.
  const std::string header =
      read_text(fs::path(KINEGEN_TEST_TMP).parent_path() / "generated/dwell_slider_crank.hpp");
  const std::string kernel =
      read_text(fs::path(KINEGEN_SOURCE_DIR) / "runtime/include/kinegen/kernels/motion_law.hpp");
  const std::string begin = "// kinegen-kernel-begin motion_law\n";
  const auto b = kernel.find(begin), e = kernel.find("  // kinegen-kernel-end motion_law\n");
  REQUIRE(b != std::string::npos);
  REQUIRE(e != std::string::npos);
  CHECK(header.find(kernel.substr(b + begin.size(), e + 1 - b - begin.size())) !=
        std::string::npos);
}

TEST_CASE("laws: a header without a law carries no motion_law kernel", "[laws]") {
  const std::string header = read_text(fs::path(KINEGEN_SOURCE_DIR) / "generated/slider_crank.hpp");
  REQUIRE(!header.empty());
  CHECK(header.find("motion_law") == std::string::npos);
}

TEST_CASE("laws: the complex step through the laws equals their derivatives", "[laws]") {
  using C = std::complex<double>;
  const auto model = cg::CompiledModel::from_file(mechanism_path());
  cg::ModelEvaluator<C> ce(*model);
  cg::ModelEvaluator<double> de(*model);
  const int nq = model->nq(), nc = model->nc();
  const double h = 1e-30;
  double worst_t = 0, worst_tt = 0, worst_q = 0;
  for (int k = -4; k <= 20; ++k) {
    const double t = k / 4.0;  // lands on the kinks
    for (double phi : {-0.3, 0.0, 0.7, kPi / 2, 2.0}) {
      std::vector<double> q(nq, 0.0), zero(nq, 0.0);
      q[2] = phi, q[3] = 3.5, q[7] = 0.2;
      std::vector<C> qc(q.begin(), q.end()), zc(nq, C(0)), out(nc);
      std::vector<double> nu(nc), gamma(nc);
      de.nu(q.data(), t, nu.data());
      de.gamma(q.data(), zero.data(), t, gamma.data());
      // Phi_t = -nu: the step in t.
      ce.phi(qc.data(), C(t, h), out.data());
      for (int r = 0; r < nc; ++r) worst_t = std::max(worst_t, std::abs(out[r].imag() / h + nu[r]));
      // With qd = 0, gamma = -Phi_tt = d nu / dt.
      ce.nu(qc.data(), C(t, h), out.data());
      for (int r = 0; r < nc; ++r)
        worst_tt = std::max(worst_tt, std::abs(out[r].imag() / h - gamma[r]));
      // Phi_q's column of phi_crank, which the follower's cycloidal reads.
      Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(nc, nq);
      de.jacobian(q.data(), t, jac);
      std::vector<C> qs = qc;
      qs[2] += C(0, h);
      ce.phi(qs.data(), C(t), out.data());
      for (int r = 0; r < nc; ++r)
        worst_q = std::max(worst_q, std::abs(out[r].imag() / h - jac(r, 2)));
    }
  }
  INFO("worst: Phi_t " << worst_t << ", Phi_tt " << worst_tt << ", Phi_q " << worst_q);
  CHECK(worst_t < 1e-14);
  CHECK(worst_tt < 1e-13);
  CHECK(worst_q < 1e-14);
}

TEST_CASE("laws: GiNaC's kinegen_law differentiates within the family and evaluates exactly",
          "[laws]") {
  using GiNaC::ex;
  using GiNaC::numeric;
  const GiNaC::symbol x("x");
  for (int law = 0; law < 4; ++law) {
    CAPTURE(law);
    const ex f = cg::kinegen_law(law, 0, 3 * x);
    CHECK(f.diff(x).is_equal(3 * cg::kinegen_law(law, 1, 3 * x)));
    CHECK(f.diff(x, 2).is_equal(9 * cg::kinegen_law(law, 2, 3 * x)));
    // Clamped at exact arguments: exact 0 and 1 (derivatives 0).
    CHECK(ex(cg::kinegen_law(law, 0, numeric(-1, 3))).is_equal(0));
    CHECK(ex(cg::kinegen_law(law, 0, 1)).is_equal(1));
    CHECK(ex(cg::kinegen_law(law, 2, 1)).is_equal(0));
    CHECK(ex(cg::kinegen_law(law, 0, 0)).is_equal(0));
    // 40 digits against the kernel in double at a point inside.
    const numeric v = cg::motion_law_high_precision(law, 1, numeric("0.3"));
    CHECK(v.to_double() == Approx(kinegen::kernels::motion_law(law, 1, 0.3)).epsilon(1e-15));
  }
  // The polynomials stay exact at a rational argument: poly345(1/3) = 10/27 - 15/81 + 6/243.
  CHECK(cg::motion_law_high_precision(kinegen::kernels::kPoly345, 0, numeric(1, 3)) ==
        numeric(10, 27) - numeric(15, 81) + numeric(6, 243));
  // cycloidal at 40 digits: x - sin(2 pi x) / (2 pi), evaluated by GiNaC on its own.
  {
    const cg::DigitsGuard digits(40);
    const numeric want = GiNaC::ex_to<numeric>(
        GiNaC::evalf(ex(numeric(1, 7)) - GiNaC::sin(2 * GiNaC::Pi / 7) / (2 * GiNaC::Pi)));
    const numeric got = GiNaC::ex_to<numeric>(GiNaC::evalf(cg::kinegen_law(0, 0, numeric(1, 7))));
    CHECK(abs(got - want) < numeric(1, 10).power(38));
  }
}

TEST_CASE("laws: a wrong argument count is an error line with its YAML line, exit 2", "[laws]") {
  const std::string text = read_text(mechanism_path());
  REQUIRE(!text.empty());
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "laws";
  fs::create_directories(dir);
  struct Case {
    const char* from;
    const char* to;
    const char* item;
  };
  const Case cases[] = {
      {"poly345(t/2)", "poly345(t/2, 1)", "drivers[0]"},
      {"cycloidal(2*phi_crank/pi)", "cycloidal()", "joints[3]"},
      {"harmonic(t/4)", "harmonic(t, 4)", "forces[0]"},
      // No argument at all: GiNaC's reader would take it for any arity (it crashed on sin()).
      {"poly345(t/2)", "sin ( )", "drivers[0]"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.to);
    std::string bad = text;
    const auto at = bad.find(c.from);
    REQUIRE(at != std::string::npos);
    bad.replace(at, std::string(c.from).size(), c.to);
    const int line = 1 + static_cast<int>(std::count(bad.begin(), bad.begin() + at, '\n'));
    const fs::path file = dir / "bad.yaml", out = dir / "bad.csv";
    std::ofstream(file) << bad;
    fs::remove(out);
    // --forces: loads are read only when they are asked for.
    const auto r =
        kinegen::test::run_command({KINEGEN_EXE, "analyze", file.string(), "--t0", "0", "--t1", "1",
                                    "--steps", "4", "--forces", "-o", out.string()});
    CAPTURE(r.err);
    CHECK(r.exit_code == 2);
    CHECK(r.err.rfind("error: " + file.string() + ":" + std::to_string(line) + ": " + c.item, 0) ==
          0);
    CHECK(r.err.find("arguments") != std::string::npos);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(!fs::exists(out));
  }
}

TEST_CASE("laws: analyze --forces balances a torque that follows a law", "[laws]") {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "laws";
  fs::create_directories(dir);
  const fs::path out = dir / "forces.csv";
  const auto r =
      kinegen::test::run_command({KINEGEN_EXE, "analyze", mechanism_path(), "--t0", "-1", "--t1",
                                  "5", "--steps", "24", "--forces", "-o", out.string()});
  REQUIRE(r.exit_code == 0);
  std::istringstream in(read_text(out));
  std::string line;
  REQUIRE(std::getline(in, line));
  std::vector<std::string> names;
  {
    std::istringstream h(line);
    for (std::string n; std::getline(h, n, ',');) names.push_back(n);
  }
  const auto col = std::find(names.begin(), names.end(), "lift.effort") - names.begin();
  REQUIRE(col < static_cast<long>(names.size()));
  int rows = 0;
  while (std::getline(in, line)) {
    std::vector<double> v;
    std::istringstream s(line);
    for (std::string x; std::getline(s, x, ',');) v.push_back(std::stod(x));
    CAPTURE(v[0]);
    // Massless bodies: the actuator holds the crank against the load alone.
    CHECK(v[col] == Approx(-kTau * harmonic(v[0] / 4)).margin(1e-14));
    ++rows;
  }
  CHECK(rows == 25);
}

TEST_CASE("laws: kinegen check's three methods agree with the symbolic derivatives", "[laws]") {
  const auto model = cg::CompiledModel::from_file(mechanism_path());
  for (double t : {0.0, 1.0, 2.0, 3.5}) {  // on a kink, inside the rises, on the dwell's end
    cg::CheckOptions options;
    options.samples = 10;
    options.t = t;
    const auto rows = cg::check_derivatives(*model, options);
    CHECK(rows.size() == 9);
    for (const auto& row : rows) {
      INFO("t = " << t << ": " << row.block << " " << row.method << " " << row.max_rel);
      CHECK(row.ok());
    }
  }
}
