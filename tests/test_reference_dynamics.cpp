// The high-precision reference of forward dynamics (analysis/reference_dynamics.hpp,
// `kinegen simulate --reference D`), against independent truths:
//  1. the pendulum released from horizontal: its half period (a stop_when root) against the
//     elliptic-integral closed form T/2 = 2 sqrt(I / (m g a)) K(1/2), K by the
//     arithmetic-geometric mean in GiNaC's own arithmetic at D + 10 digits, to ~D - 5 digits;
//  2. energy conservation of a four-bar under gravity and the power balance of a pendulum on
//     a cart with a prescribed motion (the work integral of the prescribed driver's power);
//  3. self-consistency: D and D + 10 digits agree to ~D - 5 digits;
//  4. the double simulation (CVODE at rtol 1e-12) against the reference;
//  5. the command line: --reference D writes simulate's columns, and bad D exits 2.
// The long sweeps are tagged [release]: they run in the Release build (the ctest entry
// release.reference_dynamics), not under the sanitizers, where CLN's arithmetic runs about
// 50x slower (41 min for this file); the sanitizers run the other cases, the same code paths.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/reference_dynamics.hpp"
#include "kinegen/codegen/analysis/simulate.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"
#include "support/run_command.hpp"

namespace {

namespace cg = kinegen::codegen;
namespace fs = std::filesystem;
using GiNaC::ex;
using GiNaC::numeric;

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// A mechanism file written into the test's temporary folder.
std::string write_yaml(const std::string& name, const std::string& text) {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "reference_dynamics";
  fs::create_directories(dir);
  const fs::path p = dir / (name + ".yaml");
  std::ofstream(p) << text;
  return p.string();
}

std::string pendulum_text() {
  return read_text(fs::path(KINEGEN_SOURCE_DIR) / "examples/dynamics/pendulum.yaml");
}

// The pendulum of examples/dynamics/pendulum.yaml, stopped where theta.v crosses 0 from
// below: half a swing, from horizontal (theta = 0) through the bottom to theta = -pi.
std::string pendulum_half_period_file() {
  return write_yaml("pendulum_half", pendulum_text() + "stop_when: theta.v\n");
}

struct Run {
  std::vector<cg::ReferenceSimulatedRow> rows;
  cg::ReferenceSimulationStats stats;
  double seconds = 0;
};

Run reference(const std::string& file, const cg::TimeGrid& grid, int digits) {
  cg::BuildOptions build;
  build.free_as_state = true;
  const auto model = cg::CompiledModel::from_file(file, {}, build);
  const cg::ForceModel forces = cg::derive_forces(*model);
  Run r;
  const auto start = std::chrono::steady_clock::now();
  r.stats = cg::run_reference_simulation_exact(
      *model, forces, grid, digits,
      [&](const cg::ReferenceSimulatedRow& row) { r.rows.push_back(row); });
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

// The rows' times of a reference run, kept in `times` also when it throws.
void reference_rows(const std::string& file, const cg::TimeGrid& grid, int digits,
                    std::vector<double>& times) {
  cg::BuildOptions build;
  build.free_as_state = true;
  const auto model = cg::CompiledModel::from_file(file, {}, build);
  const cg::ForceModel forces = cg::derive_forces(*model);
  cg::run_reference_simulation(*model, forces, grid, digits,
                               [&](const cg::SimulatedRow& row) { times.push_back(row.state.t); });
}

std::vector<cg::SimulatedRow> in_double(const std::string& file, const cg::TimeGrid& grid,
                                        double rtol, double atol) {
  cg::BuildOptions build;
  build.free_as_state = true;
  const auto model = cg::CompiledModel::from_file(file, {}, build);
  const cg::ForceModel forces = cg::derive_forces(*model);
  cg::SimulateOptions o;
  o.rtol = rtol;
  o.atol = atol;
  std::vector<cg::SimulatedRow> rows;
  cg::run_simulation(
      *model, forces, grid, [&](const cg::SimulatedRow& r) { rows.push_back(r); }, o);
  return rows;
}

// |a - b| as a double, the difference taken in high precision.
double gap(const numeric& a, const numeric& b) { return GiNaC::abs(a - b).to_double(); }

// K(m) = pi / (2 AGM(1, sqrt(1 - m))), at the current GiNaC::Digits.
numeric elliptic_k(const numeric& m) {
  const auto root = [](const numeric& x) {
    return GiNaC::ex_to<numeric>(GiNaC::evalf(GiNaC::sqrt(ex(x))));
  };
  numeric a = 1, b = root(1 - m);
  const numeric small = numeric(10).power(-(GiNaC::Digits - 3));
  while (GiNaC::abs(a - b) > small) {
    const numeric next = (a + b) / 2;
    b = root(a * b);
    a = next;
  }
  const numeric pi = GiNaC::ex_to<numeric>(GiNaC::evalf(GiNaC::Pi));
  return pi / (2 * a);
}

// The pendulum's half period: m = 1, a = 1/2, g = 981/100, I about the pin = m (2a)^2 / 3.
numeric pendulum_half_period(int digits) {
  const cg::DigitsGuard guard(digits);
  const numeric inertia = numeric(1, 3), mga = numeric(981, 200);
  const numeric s = GiNaC::ex_to<numeric>(GiNaC::evalf(GiNaC::sqrt(ex(inertia / mga))));
  return 2 * s * elliptic_k(numeric(1, 2));
}

}  // namespace

TEST_CASE("reference dynamics: the pendulum's half period matches the elliptic integral",
          "[reference_dynamics][release]") {
  for (const int digits : {20, 30, 60}) {
    const Run r = reference(pendulum_half_period_file(), {0, 2, 4}, digits);
    const cg::ReferenceSimulatedRow& last = r.rows.back();
    const numeric want = pendulum_half_period(digits + 10);
    const double error = gap(last.row.t, want) / want.to_double();
    // theta = -pi there (the swing ends opposite its start), found with the root.
    const cg::DigitsGuard guard(digits + 10);
    const numeric pi = GiNaC::ex_to<numeric>(GiNaC::evalf(GiNaC::Pi));
    const double angle = gap(last.z[0], -pi);
    INFO("digits " << digits << ": half period relative error " << error << ", theta + pi " << angle
                   << "; " << r.stats.steps << " steps, " << r.stats.rejected << " rejected, "
                   << r.stats.evaluations << " evaluations, column " << r.stats.largest_column
                   << ", " << r.seconds << " s");
    CHECK(r.rows.size() == 3);  // t = 0, 0.5 and the root (before t = 1)
    CHECK(error < std::pow(10.0, -(digits - 5)));
    CHECK(angle < std::pow(10.0, -(digits - 5)));
    // A conservative model: the energy balance is rounding and truncation only.
    for (const auto& row : r.rows)
      CHECK(std::abs(row.balance.to_double()) < 2.5 * std::pow(10.0, -(digits - 5)));
    WARN("pendulum half period, " << digits << " digits: relative error " << error << ", "
                                  << r.stats.evaluations << " evaluations, " << r.seconds << " s");
  }
}

namespace {

// A crank-rocker four-bar (Grashof) under gravity, released at rest with the crank
// horizontal, with an optional viscous damper on the rocker's bearing.
std::string four_bar_file(const std::string& name, const std::string& damping) {
  return write_yaml(name, R"yaml(name: )yaml" + name + R"yaml(
parameters:
  a: 0.1
  b: 0.35
  c: 0.25
  d: 0.3
gravity: [0, -9.81]
bodies:
  - {name: crank, q0: [0, 0, 0], mass: 0.4, inertia: 0.0004, com: ["a/2", 0]}
  - {name: coupler, q0: [0.1, 0, 0.78], mass: 1.2, inertia: 0.012, com: ["b/2", 0.02]}
  - {name: rocker, q0: [0.3, 0, 1.37], mass: 0.9, inertia: 0.005, com: ["c/2", 0]}
joints:
  - {type: revolute, name: O2, i: ground, j: crank}
  - {type: revolute, name: A, i: crank, j: coupler, si: [a, 0]}
  - {type: revolute, name: B, i: coupler, j: rocker, si: [b, 0], sj: [c, 0]}
  - {type: revolute, name: O4, i: ground, j: rocker, si: [d, 0]}
free:
  - {type: absolute_angle, name: theta, body: crank, value0: 0, v0: 0}
forces:
  - {type: rotational_spring_damper, name: bearing, i: ground, j: rocker, stiffness: 0,
     damping: )yaml" + damping +
                              R"yaml(, angle0: 0}
points:
  - {name: P, body: coupler, s: ["b/2", 0.05]}
)yaml");
}

// A pendulum hanging from a cart whose motion is prescribed (x = 0.2 sin 3t): the drivers do
// work, which the reference takes from the multipliers (power -lambda nu).
std::string cart_pendulum_file() {
  return write_yaml("cart_pendulum", R"yaml(name: cart_pendulum
gravity: [0, -9.81]
bodies:
  - {name: cart, q0: [0, 0, 0], mass: 2.0, inertia: 0.1}
  - {name: rod, q0: [0, 0, -1.2], mass: 0.5, inertia: 0.02, com: [0.4, 0]}
joints:
  - {type: revolute, name: pin, i: cart, j: rod}
drivers:
  - {type: absolute_x, name: cx, body: cart, f: "0.2*sin(3*t)"}
  - {type: absolute_y, name: cy, body: cart, f: "0"}
  - {type: absolute_angle, name: cphi, body: cart, f: "0"}
free:
  - {type: absolute_angle, name: theta, body: rod, v0: 0.5}
)yaml");
}

// The largest |balance| over the rows, against the energy scale (kinetic + potential at t0,
// at least 1 J, as the integrators scale the work).
double worst_balance(const Run& r) {
  const double scale =
      std::max(1.0, std::abs((r.rows[0].kinetic + r.rows[0].potential).to_double()));
  double worst = 0;
  for (const auto& row : r.rows) worst = std::max(worst, std::abs(row.balance.to_double()));
  return worst / scale;
}

// The largest difference of the free coordinates (scaled as the integrators do: angles in
// radians) between two high-precision runs on the same grid.
double worst_gap(const Run& a, const Run& b) {
  double worst = 0;
  for (std::size_t k = 0; k < a.rows.size(); ++k)
    for (std::size_t i = 0; i < a.rows[k].z.size(); ++i)
      worst = std::max({worst, gap(a.rows[k].z[i], b.rows[k].z[i]),
                        gap(a.rows[k].zd[i], b.rows[k].zd[i]) /
                            std::max(1.0, std::abs(b.rows[k].zd[i].to_double()))});
  return worst;
}

}  // namespace

TEST_CASE("reference dynamics: energy and power balances hold to ~D - 5 digits",
          "[reference_dynamics][release][balances]") {
  // 25 digits: a balance to 1e-20 is far beyond what double arithmetic could give, at a
  // third of the cost of 30. Release only: its three runs reach no code that the sanitizer
  // pass's reference cases (the convergence, the breakpoints, the command line) do not.
  constexpr int kDigits = 25;
  const double bound = std::pow(10.0, -(kDigits - 5));
  SECTION("a four-bar under gravity conserves its energy") {
    const Run r = reference(four_bar_file("four_bar_gravity", "0"), {0, 1, 10}, kDigits);
    INFO(r.stats.steps << " steps, " << r.stats.evaluations << " evaluations, " << r.seconds
                       << " s");
    CHECK(worst_balance(r) < bound);
    // It moves: the crank swings through more than a quarter turn.
    double reach = 0;
    for (const auto& row : r.rows) reach = std::max(reach, std::abs(row.z[0].to_double()));
    CHECK(reach > 1.5);
  }
  SECTION("with a damper, the work equals the energy lost") {
    const Run r = reference(four_bar_file("four_bar_damper", "0.05"), {0, 1, 10}, kDigits);
    CHECK(worst_balance(r) < bound);
    CHECK(r.rows.back().work.to_double() < -1e-3);  // the damper took energy out
  }
  SECTION("a prescribed motion's work (from the multipliers) balances the energy") {
    const Run r = reference(cart_pendulum_file(), {0, 2, 20}, kDigits);
    CHECK(worst_balance(r) < bound);
    double work = 0;
    for (const auto& row : r.rows) work = std::max(work, std::abs(row.work.to_double()));
    CHECK(work > 1e-2);  // the cart's driver does work
  }
}

TEST_CASE("reference dynamics: D and D + 10 digits agree to ~D - 5 digits",
          "[reference_dynamics][release]") {
  const std::string file = four_bar_file("four_bar_gravity", "0.05");
  // 20 against 30 digits (the pendulum's test above reaches 60 against a closed form).
  const Run a = reference(file, {0, 1, 5}, 20), b = reference(file, {0, 1, 5}, 30);
  REQUIRE(a.rows.size() == b.rows.size());
  const double worst = worst_gap(a, b);
  WARN("four-bar with damper to t = 1: 20 against 30 digits " << worst << " (" << a.seconds
                                                              << " s and " << b.seconds << " s)");
  CHECK(worst < 1e-15);
}

TEST_CASE("reference dynamics: the double simulation converges to the reference",
          "[reference_dynamics]") {
  // CVODE's global error is not bounded by rtol (it grows with the steps and the motion's
  // sensitivity): measured at rtol = atol = 1e-12, 2e-11 (pendulum), 1e-9 (four-bar) and
  // 4e-12 (cart). The test: below 1e-8, and at least 10 times below the error at 1e-10.
  for (const std::string& file :
       {std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/pendulum.yaml",
        four_bar_file("four_bar_gravity", "0"), cart_pendulum_file()}) {
    const cg::TimeGrid grid{0, 1, 10};
    const Run r = reference(file, grid, 20);  // its error, ~1e-15, is far below double's here
    const auto error = [&](double tol) {
      const std::vector<cg::SimulatedRow> d = in_double(file, grid, tol, tol);
      REQUIRE(d.size() == r.rows.size());
      double worst = 0;
      for (std::size_t k = 0; k < d.size(); ++k) {
        for (int i = 0; i < d[k].z.size(); ++i)
          worst = std::max(worst, gap(cg::exact_numeric(d[k].z[i]), r.rows[k].z[i]));
        for (int i = 0; i < d[k].state.q.size(); ++i)
          worst = std::max(worst, gap(cg::exact_numeric(d[k].state.q[i]), r.rows[k].row.q[i]));
      }
      return worst;
    };
    const double fine = error(1e-12), coarse = error(1e-10);
    WARN(fs::path(file).filename().string() << ": double against the reference to t = 1: " << fine
                                            << " at rtol 1e-12, " << coarse << " at 1e-10");
    CHECK(fine < 1e-8);
    CHECK(fine * 10 < coarse);
    // The rounded row is the row the CSV writer prints.
    const cg::SimulatedRow rounded = cg::to_simulated_row(r.rows.back());
    CHECK(rounded.z[0] == r.rows.back().z[0].to_double());
    CHECK(rounded.state.t == grid.t1);
  }
}

TEST_CASE("reference dynamics: a singular position ends the run after its rows",
          "[reference_dynamics]") {
  // The pendulum with its tip's height as the free coordinate: at the bottom dy/dtheta = 0,
  // q is no function of z there (released at y = -0.8, it gets there near t = 0.42).
  std::string text = pendulum_text();
  const std::string from = "type: absolute_angle\n    name: theta\n    body: rod\n    value0: 0";
  REQUIRE(text.find(from) != std::string::npos);
  text.replace(text.find(from), from.size(),
               "type: absolute_y\n    name: theta\n    body: rod\n    s: [\"2*a\", 0]\n"
               "    value0: -0.8");
  const std::string file = write_yaml("pendulum_tip_height", text);
  std::vector<double> times;
  std::string message;
  try {
    reference_rows(file, {0, 1, 10}, 25, times);
  } catch (const cg::AnalysisError& e) {
    message = e.what();
  }
  CHECK(message.find("singular position") != std::string::npos);
  CHECK(message.find("pendulum_tip_height.yaml") != std::string::npos);
  CHECK(times.size() == 5);  // t = 0 .. 0.4
}

TEST_CASE("reference dynamics: kinegen simulate --reference", "[reference_dynamics][cli]") {
  const std::string file = std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/pendulum.yaml";
  const auto run = [&](const std::vector<std::string>& extra) {
    std::vector<std::string> argv{KINEGEN_EXE, "simulate", file, "--t1", "1", "--steps", "4"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return kinegen::test::run_command(argv);
  };
  const auto ref = run({"--reference", "25"});
  const auto dbl = run({"--rtol", "1e-12", "--atol", "1e-12"});
  REQUIRE(ref.exit_code == 0);
  REQUIRE(dbl.exit_code == 0);
  // The same columns and rows as the double run, the values to its error.
  const auto lines = [](const std::string& s) {
    std::vector<std::string> v;
    for (std::size_t p = 0, q; p < s.size(); p = q + 1) {
      q = s.find('\n', p);
      if (q == std::string::npos) q = s.size();
      v.push_back(s.substr(p, q - p));
    }
    return v;
  };
  const auto a = lines(ref.out), b = lines(dbl.out);
  REQUIRE(a.size() == 6);  // header and 5 rows
  CHECK(a[0] == b[0]);
  const auto column = [](const std::string& row, int c) {
    std::size_t p = 0;
    for (int k = 0; k < c; ++k) p = row.find(',', p) + 1;
    return std::stod(row.substr(p, row.find(',', p) - p));
  };
  CHECK(std::abs(column(a[5], 3) - column(b[5], 3)) < 1e-9);  // rod.phi at t = 1
  for (const char* bad : {"10", "1001"}) {
    const auto r = run({"--reference", bad});
    CHECK(r.exit_code == 2);
    CHECK(r.err.rfind("error: ", 0) == 0);
    CHECK(r.out.empty());
  }
}

// ---------------------------------------------------------------------------------------------
// Breakpoints: no extrapolation step spans a driver's or a load's kink (analysis/breakpoints.hpp).

namespace {

std::string driven_pendulum_text() {
  return read_text(fs::path(KINEGEN_SOURCE_DIR) / "examples/dynamics/driven_pendulum.yaml");
}

// The driven pendulum with its shaker's law replaced by `law` (the rest of the driver's entry)
// and `forces` appended (a YAML forces: section or "").
std::string driven_pendulum_file(const std::string& name, const std::string& law,
                                 const std::string& forces = "") {
  std::string text = driven_pendulum_text();
  const std::string from = "f: \"amplitude*sin(omega*t)\"";
  REQUIRE(text.find(from) != std::string::npos);
  text.replace(text.find(from), from.size(), law);
  return write_yaml(name, text + forces);
}

// The largest difference of z and zd at the last row, relative to max(|value|, 1).
double last_row_gap(const cg::ReferenceSimulatedRow& ref, const cg::SimulatedRow& d) {
  double worst = 0;
  for (std::size_t i = 0; i < ref.z.size(); ++i) {
    worst =
        std::max(worst, gap(ref.z[i], cg::exact_numeric(d.z[i])) / std::max(1.0, std::abs(d.z[i])));
    worst = std::max(worst,
                     gap(ref.zd[i], cg::exact_numeric(d.zd[i])) / std::max(1.0, std::abs(d.zd[i])));
  }
  return worst;
}

}  // namespace

TEST_CASE("reference dynamics: the press with flywheel across its poly345 strokes",
          "[reference_dynamics][release][breakpoints]") {
  // The forming force is poly345 of the ram's depth and speed: kinks of the state, located and
  // restarted from. theta at t = 3: 20.2092458080 (CVODE at rtol 1e-13, RK4 at h = 1e-4,
  // Simbody at 1e-12 and 40 digits agree to 1e-11); with one row or 300 alike.
  const std::string file =
      (fs::path(KINEGEN_SOURCE_DIR) / "examples/dynamics/press_flywheel.yaml").string();
  const double want = 20.2092458080;
  std::vector<double> theta;
  for (const int steps : {1, 300}) {
    const Run r = reference(file, {0, 3, steps}, 20);
    theta.push_back(r.rows.back().z[0].to_double());
    WARN("press_flywheel, --reference 20 --steps "
         << steps << ": theta(3) = " << std::setprecision(14) << theta.back() << " (" << r.seconds
         << " s, " << r.stats.steps << " steps)");
    CHECK(std::abs(theta.back() - want) < 1e-10 * want);
  }
  const std::vector<cg::SimulatedRow> d = in_double(file, {0, 3, 1}, 1e-13, 1e-15);
  CHECK(std::abs(d.back().z[0] - theta[0]) < 1e-10 * want);
  CHECK(std::abs(theta[0] - theta[1]) < 1e-12 * want);
}

TEST_CASE(
    "reference dynamics: against CVODE at rtol 1e-13 on laws in pieces, periods, tables "
    "and clamped laws, independently of --steps",
    "[reference_dynamics][breakpoints]") {
  // The driven pendulum's shaker: a periodic dwell-rise (poly345) -dwell-return (harmonic, whose
  // f'' jumps), a periodic table, and a clamped cycloidal torque pulse on the rod.
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "reference_dynamics";
  fs::create_directories(dir);
  {
    std::ofstream csv(dir / "shaker.csv");
    csv << "t,value\n";
    for (int k = 0; k <= 8; ++k)
      csv << k / 8.0 << "," << (k == 8 ? 0.0 : 0.1 * std::sin(2 * M_PI * k / 8.0)) << "\n";
  }
  const std::vector<std::string> files = {
      driven_pendulum_file("shaker_pieces",
                           "period: 1, f: [{until: 0.25, f: \"0\"}, {until: 0.5, f: "
                           "\"amplitude*poly345(4*t - 1)\"}, {until: 0.75, f: \"amplitude\"}, "
                           "{f: \"amplitude*(1 - harmonic(4*t - 3))\"}]"),
      driven_pendulum_file("shaker_table", "period: 1, table: shaker.csv"),
      driven_pendulum_file(
          "shaker_kick", "f: \"amplitude*sin(omega*t)\"",
          "forces:\n  - {type: torque, name: kick, body: rod, value: \"0.5*cycloidal(t/0.3) - "
          "0.5*cycloidal((t - 0.6)/0.3)\"}\n")};
  for (const std::string& file : files) {
    const double t1 = 1.3;
    const Run one = reference(file, {0, t1, 1}, 20), three = reference(file, {0, t1, 3}, 20);
    const std::vector<cg::SimulatedRow> d = in_double(file, {0, t1, 1}, 1e-13, 1e-15);
    const double cvode = last_row_gap(one.rows.back(), d.back());
    const double steps = last_row_gap(one.rows.back(), cg::to_simulated_row(three.rows.back()));
    WARN(fs::path(file).filename().string()
         << " to t = " << t1 << ": reference against CVODE (rtol 1e-13, atol 1e-15) " << cvode
         << ", --steps 1 against 3 " << steps << " (" << one.seconds << " s)");
    CHECK(cvode < 1e-10);
    CHECK(steps < 1e-12);
  }
}

TEST_CASE("reference dynamics: --reference D accepts 16 to 60 digits",
          "[reference_dynamics][cli]") {
  const std::string file = std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/pendulum.yaml";
  const auto run = [&](const std::string& digits) {
    return kinegen::test::run_command(
        {KINEGEN_EXE, "simulate", file, "--t1", "0.1", "--steps", "1", "--reference", digits});
  };
  for (const char* bad : {"15", "61", "200"}) {
    const auto r = run(bad);
    INFO(bad << ": " << r.err);
    CHECK(r.exit_code == 2);
    CHECK(r.err.find("between 16 and 60") != std::string::npos);
    CHECK(r.out.empty());
  }
  for (const char* good : {"16", "60"}) {
    const auto r = run(good);
    INFO(good << ": " << r.err);
    CHECK(r.exit_code == 0);
  }
}

TEST_CASE("reference dynamics: the first SIGINT stops --reference at once, rows kept (exit 1)",
          "[reference_dynamics][cli]") {
  // One row at t0, the next at t = 1000: without an interruption point inside the steps the run
  // would not stop before that row.
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "reference_sigint";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path target = dir / "out.csv", err = dir.parent_path() / "reference_sigint.txt";
  const std::string file = std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/pendulum.yaml";
  kinegen::test::ChildProcess child({KINEGEN_EXE, "simulate", file, "--t1", "2000", "--steps", "2",
                                     "--reference", "60", "-o", target.string()},
                                    "/dev/null", "/dev/null", err.string());
  // Well into the first step: after 2 s of the child's CPU time (reading the pendulum and
  // solving t0 take a fraction of that), however loaded the machine.
  const auto cpu_seconds = [&] {
    std::ifstream stat("/proc/" + std::to_string(child.pid) + "/stat");
    std::string text((std::istreambuf_iterator<char>(stat)), std::istreambuf_iterator<char>());
    std::istringstream fields(text.substr(text.rfind(')') + 2));
    std::string field;
    long ticks = 0;
    for (int k = 3; k <= 15 && fields >> field; ++k)
      if (k >= 14) ticks += std::stol(field);  // utime, stime
    return static_cast<double>(ticks) / ::sysconf(_SC_CLK_TCK);
  };
  for (int k = 0; k < 6000 && cpu_seconds() < 2; ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const auto sent = std::chrono::steady_clock::now();
  ::kill(child.pid, SIGINT);
  const int status = child.wait();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
  const std::string message = read_text(err);
  INFO(message);
  WARN("--reference 60 stopped " << seconds * 1e3 << " ms after SIGINT");
  CHECK(status == 1);
  CHECK(message.rfind("error: " + file + ": interrupted at t = ", 0) == 0);
  CHECK(seconds < 30);  // not a timing test: the old code ran on to the row at t = 1000
  // The row at t0 is kept, under the header.
  const std::string csv = read_text(target);
  CHECK(std::count(csv.begin(), csv.end(), '\n') == 2);
}

// ---------------------------------------------------------------------------------------------
// stop_when on the reference: the first crossing from < 0 to >= 0 after t0, brief ones too.

namespace {

struct StopRun {
  std::vector<cg::ReferenceSimulatedRow> rows;
  cg::ReferenceSimulationStats stats;
};

StopRun stop_run(const std::string& name, const std::string& stop_when, double t1, int steps,
                 int digits = 20) {
  const std::string file = write_yaml(name, pendulum_text() + "stop_when: \"" + stop_when + "\"\n");
  cg::BuildOptions build;
  build.free_as_state = true;
  const auto model = cg::CompiledModel::from_file(file, {}, build);
  const cg::ForceModel forces = cg::derive_forces(*model);
  StopRun r;
  r.stats = cg::run_reference_simulation_exact(
      *model, forces, {0, t1, steps}, digits,
      [&](const cg::ReferenceSimulatedRow& row) { r.rows.push_back(row); });
  return r;
}

}  // namespace

TEST_CASE(
    "reference dynamics: stop_when finds a brief dip above 0 and the first of fast "
    "oscillations",
    "[reference_dynamics][release][stop_when]") {
  // 1e-5 - 40 (t - 0.5)^2 is above 0 only on 0.5 -+ 5e-4: its first crossing is 0.5 - 5e-4.
  for (const double dip : {1e-5, 1e-9}) {
    const std::string expr = cg::format_number(dip) + " - 40*(t - 0.5)^2";
    const StopRun r = stop_run("stop_dip", expr, 1, 1);
    const double want = 0.5 - std::sqrt(dip / 40);
    INFO(expr << ": stopped " << r.stats.stopped << " at " << r.stats.stop_time);
    CHECK(r.stats.stopped);
    REQUIRE(r.rows.size() == 2);
    CHECK(std::abs(r.rows.back().row.t.to_double() - want) < 1e-13);
  }
  // sin(1e4 t) is 0 at t0 (no crossing), positive, then crosses up first at 2 pi / 1e4.
  const StopRun r = stop_run("stop_sin", "sin(10000*t)", 0.01, 1);
  CHECK(r.stats.stopped);
  CHECK(std::abs(r.stats.stop_time - 2 * M_PI / 1e4) < 1e-15);
  // Above 0 at t0: one row, at t0.
  const StopRun at_t0 = stop_run("stop_at_t0", "1 - t", 1, 4);
  CHECK(at_t0.stats.stopped);
  CHECK(at_t0.rows.size() == 1);
  CHECK(at_t0.stats.stop_time == 0);
}

TEST_CASE(
    "reference dynamics: simulate --reference says where stop_when stopped it, and names "
    "a stop_when that is no real number",
    "[reference_dynamics][stop_when][cli]") {
  const std::string dip =
      write_yaml("stop_dip_cli", pendulum_text() + "stop_when: \"1e-5 - 40*(t - 0.5)^2\"\n");
  const auto r = kinegen::test::run_command(
      {KINEGEN_EXE, "simulate", dip, "--t1", "1", "--steps", "1", "--reference", "20"});
  INFO(r.err);
  CHECK(r.exit_code == 0);
  CHECK(r.err.find("stopped at t = 0.4995") != std::string::npos);
  CHECK(r.err.find(": 1e-5 - 40*(t - 0.5)^2 crossed 0") != std::string::npos);
  const std::string text = pendulum_text();
  const auto line = std::count(text.begin(), text.end(), '\n') + 1;
  const std::string nan = write_yaml("stop_nan", text + "stop_when: \"sqrt(0.5 - t) - 10\"\n");
  const auto n = kinegen::test::run_command(
      {KINEGEN_EXE, "simulate", nan, "--t1", "1", "--steps", "4", "--reference", "20"});
  INFO(n.err);
  CHECK(n.exit_code == 1);
  CHECK(n.err.rfind("error: " + nan + ":" + std::to_string(line) + ": stop_when: ", 0) == 0);
  CHECK(std::count(n.out.begin(), n.out.end(), '\n') == 3);  // header, t = 0 and 0.25
}
