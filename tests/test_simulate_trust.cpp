// `kinegen simulate` on CVODE: a run that exits 0 is a run to trust. The energy balance as a
// witness with a bound that follows from the tolerances (stiff springs end either within it or
// with exit 1), no false failures (force-free motion, a fine grid, a stiff start), the step
// limit over the whole run, stop_when's first crossing (randomized dips, fast oscillations,
// crossings near rows) against closed forms, --atol following --rtol, rows independent of
// --steps, and the messages (-v, the stop line, a non-finite stop_when, the tolerance range).
// [release]: the three long runs (2 minutes under the sanitizers) run in an optimized build only
// (tests/CMakeLists.txt); the other cases reach the same integrator code under the sanitizers.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/reference_dynamics.hpp"
#include "kinegen/codegen/analysis/simulate.hpp"
#include "support/files.hpp"
#include "support/run_command.hpp"

namespace {

namespace fs = std::filesystem;
namespace kc = kinegen::codegen;
using kinegen::test::CommandResult;
using kinegen::test::write_text;

constexpr double kPi = 3.14159265358979323846;

fs::path scratch(const std::string& name) {
  return kinegen::test::scratch_dir("simulate_trust", name);
}

CommandResult run_kinegen(const std::vector<std::string>& args) {
  std::vector<std::string> argv{KINEGEN_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  return kinegen::test::run_command(argv, {});
}

// A CSV of numbers, its columns by name.
struct Table {
  std::vector<std::string> names;
  std::vector<std::vector<double>> columns;
  std::size_t rows() const { return columns.empty() ? 0 : columns[0].size(); }
  const std::vector<double>& operator[](const std::string& name) const {
    const auto at = std::find(names.begin(), names.end(), name);
    INFO("column " << name);
    REQUIRE(at != names.end());
    return columns[at - names.begin()];
  }
};

Table read_csv(const fs::path& path) {
  std::istringstream in(kinegen::test::read_text(path));
  Table t;
  std::string line, field;
  REQUIRE(std::getline(in, line));
  std::istringstream header(line);
  while (std::getline(header, field, ',')) t.names.push_back(field);
  t.columns.resize(t.names.size());
  while (std::getline(in, line)) {
    std::istringstream row(line);
    for (std::size_t k = 0; k < t.names.size() && std::getline(row, field, ','); ++k)
      t.columns[k].push_back(std::stod(field));
  }
  return t;
}

// Runs `simulate FILE args -o dir/out.csv`.
struct Run {
  CommandResult r;
  Table rows;
};
Run simulate(const fs::path& yaml, std::vector<std::string> args) {
  const fs::path out = yaml.parent_path() / "out.csv";
  fs::remove(out);
  std::vector<std::string> argv{"simulate", yaml.string(), "-o", out.string()};
  argv.insert(argv.end(), args.begin(), args.end());
  Run run{run_kinegen(argv), {}};
  if (fs::exists(out)) run.rows = read_csv(out);
  return run;
}

fs::path write_yaml(const std::string& name, const std::string& text) {
  const fs::path p = scratch(name) / (name + ".yaml");
  write_text(p, text);
  return p;
}

double max_abs(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}

// A mass m on a guide held by a spring (and a damper) to ground: k, c, the start x0.
std::string oscillator(double k, double c, double x0, double m = 1) {
  std::ostringstream y;
  y.precision(17);
  y << "name: oscillator\nparameters: {m: " << m << ", k: " << k << ", c: " << c << "}\n"
    << "bodies:\n  - {name: mass, q0: [" << x0 << ", 0, 0], mass: m}\n"
    << "joints:\n  - {type: translational, name: guide, i: ground, j: mass, vi: [1, 0]}\n"
    << "free:\n  - {type: absolute_x, name: x, body: mass, value0: " << x0 << ", v0: 0}\n"
    << "forces:\n  - {type: spring_damper, name: spring, i: ground, j: mass, si: [-1, 0], "
       "sj: [0, 0], stiffness: k, damping: c, length0: 1}\n";
  return y.str();
}

// A rod of length 1 (m = 1, a = 0.5: the pendulum example) released from horizontal, with a
// stop_when and parameters of the caller's.
std::string pendulum(const std::string& stop_when, const std::string& params = "") {
  return "name: pendulum\nparameters: {m: 1.0, a: 0.5, g: 9.81" + params +
         "}\nbodies:\n  - {name: rod, q0: [0, 0, 0], mass: m, inertia: \"m*(2*a)^2/12\", "
         "com: [a, 0]}\njoints:\n  - {type: revolute, name: pivot, i: ground, j: rod}\n"
         "free:\n  - {type: absolute_angle, name: theta, body: rod, value0: 0, v0: 0}\n"
         "gravity: [0, -g]\npoints:\n  - {name: tip, body: rod, s: [\"2*a\", 0]}\n" +
         (stop_when.empty() ? "" : "stop_when: \"" + stop_when + "\"\n");
}

const char* const kDoublePendulum = R"(name: double_pendulum
parameters: {m: 1.0, l: 1.0, g: 9.81}
bodies:
  - {name: upper, q0: [0, 0, 0], mass: m, inertia: "m*l^2/12", com: ["l/2", 0]}
  - {name: lower, q0: [1, 0, 0], mass: m, inertia: "m*l^2/12", com: ["l/2", 0]}
joints:
  - {type: revolute, name: top, i: ground, j: upper}
  - {type: revolute, name: elbow, i: upper, j: lower, si: [l, 0]}
free:
  - {type: absolute_angle, name: a1, body: upper, value0: 0, v0: 0}
  - {type: absolute_angle, name: a2, body: lower, value0: 0, v0: 0}
gravity: [0, -g]
)";

}  // namespace

// --- The energy balance as a witness ----------------------------------------------------------

TEST_CASE("stiff springs end within the balance's bound or with exit 1, never with percents lost",
          "[simulate_trust][release]") {
  struct Case {
    double k, c, t1;
  };
  // The issue's cases: damped k = 1e10 and 1e12 (c for a damping ratio of 1e-3), undamped
  // k = 1e6 over 100 s; they used to exit 0 with 2.7%, 17.8% and 1.2% of the energy lost.
  for (const Case c : {Case{1e10, 2e2, 1}, Case{1e12, 2e3, 1}, Case{1e6, 0, 100}}) {
    CAPTURE(c.k, c.c, c.t1);
    const fs::path yaml = write_yaml(
        "stiff_" + std::to_string(static_cast<int>(std::log10(c.k))) + (c.c > 0 ? "_damped" : ""),
        oscillator(c.k, c.c, 0.01));
    const Run run = simulate(yaml, {"--t1", std::to_string(c.t1), "--steps", "200", "-q"});
    INFO("stderr: " << run.r.err);
    if (run.r.exit_code == 0) {
      // Within the bound, whose cap is 1e-3 of the energy scale (0.5 k x0^2 at the start).
      const double energy = 0.5 * c.k * 1e-4;
      CHECK(max_abs(run.rows["energy.balance"]) <= 1e-3 * energy);
    } else {
      CHECK(run.r.exit_code == 1);
      CHECK(run.r.err.find("energy balance is off by") != std::string::npos);
      CHECK(run.r.err.find("--rtol") != std::string::npos);
      CHECK(std::count(run.r.err.begin(), run.r.err.end(), '\n') == 1);
    }
  }
}

TEST_CASE("a small mechanism's balance is held to its own energy, not to one joule",
          "[simulate_trust][release]") {
  // A milligram on a spring, vibrating 0.1 mm: 5e-5 J. With omega^2 = 1e10 it is the 1 kg,
  // k = 1e10 oscillator, which BDF damps numerically at this tolerance; the tolerance's floor of
  // 1 J let it end with exit 0 and 1% of its energy lost. With omega^2 = 1e4 it is resolved.
  const double m = 1e-6, x0 = 1e-4;
  for (const double k : {1e4, 1e-2}) {
    CAPTURE(k);
    const fs::path yaml = write_yaml(k > 1 ? "small_stiff" : "small_soft", oscillator(k, 0, x0, m));
    const Run run = simulate(yaml, {"--t1", "1", "--steps", "200", "-q"});
    INFO("stderr: " << run.r.err);
    const double energy = 0.5 * k * x0 * x0;
    if (k < 1) REQUIRE(run.r.exit_code == 0);  // no false failure on a small, resolved motion
    if (run.r.exit_code == 0) {
      CHECK(max_abs(run.rows["energy.balance"]) <= 1e-3 * energy);
    } else {
      CHECK(run.r.exit_code == 1);
      CHECK(run.r.err.find("energy balance is off by") != std::string::npos);
      CHECK(run.r.err.find("S = 5e-05") != std::string::npos);  // the oscillator's own energy
    }
  }
}

TEST_CASE("--allow-drift turns the balance's failure into one warning with its largest value",
          "[simulate_trust][release]") {
  const fs::path yaml = write_yaml("drift", oscillator(1e6, 0, 0.01));
  const Run strict = simulate(yaml, {"--t1", "100", "--steps", "100", "--rtol", "1e-4"});
  INFO("stderr: " << strict.r.err);
  REQUIRE(strict.r.exit_code == 1);
  REQUIRE(strict.r.err.find("energy balance") != std::string::npos);
  const Run drift =
      simulate(yaml, {"--t1", "100", "--steps", "100", "--rtol", "1e-4", "--allow-drift"});
  INFO("stderr: " << drift.r.err);
  CHECK(drift.r.exit_code == 0);
  CHECK(drift.rows.rows() == 101);
  CHECK(drift.r.err.rfind("warning: ", 0) == 0);
  CHECK(std::count(drift.r.err.begin(), drift.r.err.end(), '\n') == 1);
  CHECK(drift.r.err.find("energy balance") != std::string::npos);
  CHECK(drift.r.err.find("at t = ") != std::string::npos);
}

TEST_CASE("force-free motion passes: no relative measure divides by an exchange near 0",
          "[simulate_trust]") {
  // four_bar_swing with gravity 0 and v0 = 1: nothing does work, the kinetic energy is
  // constant (it used to fail with "off by 8.6e-10 (14.4%)").
  const fs::path example = fs::path(KINEGEN_SOURCE_DIR) / "examples/dynamics/four_bar_swing.yaml";
  std::string text = kinegen::test::read_text(example);
  const auto g = text.find("gravity: [0, -9.81]");
  REQUIRE(g != std::string::npos);
  text.replace(g, 19, "gravity: [0, 0]");
  const auto v0 = text.find("v0: 0}");
  REQUIRE(v0 != std::string::npos);
  text.replace(v0, 6, "v0: 1}");
  const fs::path yaml = write_yaml("force_free", text);
  const Run run = simulate(yaml, {"--t1", "5", "--steps", "50", "-q"});
  INFO("stderr: " << run.r.err);
  REQUIRE(run.r.exit_code == 0);
  const double kinetic = run.rows["energy.kinetic"][0];
  REQUIRE(kinetic > 0);
  CHECK(max_abs(run.rows["energy.balance"]) < 1e-6 * kinetic);
}

TEST_CASE("a fine grid and a stiff start are no failures: the smallest step follows t alone",
          "[simulate_trust]") {
  SECTION("the pendulum at --steps 100000000 over 1 s") {
    // It used to fail at the first row, t = 1e-8, with "lost its accuracy" (the guard divided
    // by the energy exchanged so far, near 0 there). stop_when ends it after 1000 rows.
    const fs::path yaml = write_yaml("fine_grid", pendulum("t - 1e-5"));
    const Run run = simulate(yaml, {"--t1", "1", "--steps", "100000000", "-q"});
    INFO("stderr: " << run.r.err);
    CHECK(run.r.exit_code == 0);
    CHECK(run.rows.rows() == 1001);
    CHECK(run.rows["t"].back() == Approx(1e-5).epsilon(1e-12));
  }
  SECTION("a stiff damped spring runs alike to t1 = 2 and to t1 = 1e-3") {
    // Overdamped: its time constants are m/c = 1e-9 s and c/k = 1e-3 s, so the first steps
    // are far below 1e-12 of t1 - t0 = 2, which the minimum step used to be.
    const fs::path yaml = write_yaml("stiff_start", oscillator(1e12, 1e9, 0.01));
    const Run shortrun = simulate(yaml, {"--t1", "1e-3", "--steps", "10", "-q"});
    const Run longrun = simulate(yaml, {"--t1", "2", "--steps", "2000", "-q"});
    INFO("short: " << shortrun.r.err << "long: " << longrun.r.err);
    REQUIRE(shortrun.r.exit_code == 0);
    REQUIRE(longrun.r.exit_code == 0);
    // The same motion: the row at 1e-3 of each.
    CHECK(longrun.rows["t"][1] == Approx(1e-3));
    CHECK(longrun.rows["x"][1] == Approx(shortrun.rows["x"].back()).epsilon(1e-5).margin(1e-12));
  }
}

TEST_CASE("the integrator's step limit counts over the whole run, not per row",
          "[simulate_trust]") {
  kc::BuildOptions build;
  build.free_as_state = true;
  const auto model = kc::CompiledModel::from_mechanism(
      kc::parse_mechanism(oscillator(1e4, 0, 0.01), "osc.yaml"), {}, build);
  const kc::ForceModel forces = kc::derive_forces(*model);
  kc::SimulateOptions o;
  o.max_steps = 2000;
  // 100 periods of 0.063 s need far more than 2000 steps in all, but far fewer than 2000 in
  // any one of the 200 row intervals.
  int rows = 0;
  try {
    kc::run_simulation(
        *model, forces, {0, 6.3, 200}, [&](const kc::SimulatedRow&) { ++rows; }, o);
    FAIL("the run passed its step limit");
  } catch (const kc::AnalysisError& e) {
    CHECK(std::string(e.what()).find("2000 steps in all") != std::string::npos);
  }
  CHECK(rows > 1);
  CHECK(rows < 201);
}

// --- stop_when -------------------------------------------------------------------------------

TEST_CASE("stop_when: the first crossing of a fast oscillation, not a later one",
          "[simulate_trust]") {
  // sin(1e6 t) is 0 at t0 (no crossing), positive, then crosses 0 from below at 2 pi / 1e6.
  const fs::path yaml = write_yaml("fast", pendulum("sin(1e6*t)"));
  const Run run = simulate(yaml, {"--t1", "1", "--steps", "10"});
  INFO("stderr: " << run.r.err);
  REQUIRE(run.r.exit_code == 0);
  REQUIRE(run.rows.rows() == 2);
  CHECK(run.rows["t"].back() == Approx(2 * kPi / 1e6).epsilon(1e-9));
  CHECK(run.r.err.find("stopped at t = ") != std::string::npos);
  CHECK(run.r.err.find("sin(1e6*t) crossed 0") != std::string::npos);
}

TEST_CASE("stop_when above 0 at t0 stops there with one row; a zero at t0 is no crossing",
          "[simulate_trust]") {
  const Run above =
      simulate(write_yaml("above", pendulum("1 - t")), {"--t1", "1", "--steps", "10"});
  INFO("stderr: " << above.r.err);
  CHECK(above.r.exit_code == 0);
  CHECK(above.rows.rows() == 1);
  CHECK(above.r.err.find("stopped at t = 0") != std::string::npos);
  // theta.v is 0 at the release, then negative, and crosses 0 from below at the far end of
  // the swing (half a period, 0.9667 s from the elliptic integral).
  const Run zero =
      simulate(write_yaml("zero", pendulum("theta.v")), {"--t1", "3", "--steps", "30"});
  INFO("stderr: " << zero.r.err);
  CHECK(zero.r.exit_code == 0);
  const double k = 1.8540746773013719;  // K(1/2)
  const double half_period = 2 * std::sqrt((1.0 / 3) / (9.81 * 0.5)) * k;
  CHECK(zero.rows["t"].back() == Approx(half_period).epsilon(1e-7));
}

TEST_CASE("stop_when: randomized dips of 1e-3 to 1e-9 found at their first crossing",
          "[simulate_trust]") {
  // g = sin(w t) - 1 + d peaks at d > 0 once per period; its first crossing is at
  // asin(1 - d) / w exactly. Each run at an rtol 100 times tighter than the dip, with a grid
  // whose rows may fall near the crossing.
  std::mt19937 rng(35);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 12; ++trial) {
    const double d = std::pow(10.0, -3 - 6 * u(rng));
    const double w = std::pow(10.0, 6 * u(rng));
    const double rtol = std::max(d / 100, 1e-14);
    const double t_cross = std::asin(1 - d) / w;
    // Rows near the crossing for some trials: t1 a multiple of it.
    const int steps = 1 + static_cast<int>(u(rng) * 500);
    const double t1 = trial % 3 == 0 ? t_cross * steps / (steps - 0.5) * 3 : 10 / w;
    CAPTURE(trial, d, w, rtol, steps, t1, t_cross);
    std::ostringstream params;
    params.precision(17);
    params << ", w: " << w << ", d: " << d;
    const fs::path yaml = write_yaml("dip", pendulum("sin(w*t) - 1 + d", params.str()));
    std::ostringstream r, t;
    r.precision(17);
    t.precision(17);
    r << rtol;
    t << t1;
    const Run run = simulate(
        yaml, {"--t1", t.str(), "--steps", std::to_string(steps), "--rtol", r.str(), "-q"});
    INFO("stderr: " << run.r.err);
    REQUIRE(run.r.exit_code == 0);
    REQUIRE(run.rows.rows() >= 2);
    // Found to the time tolerance: the expression's error bound over its rate there.
    const double rate = w * std::sqrt(2 * d - d * d);
    CHECK(std::abs(run.rows["t"].back() - t_cross) <= 10 * rtol / rate + 1e-15 * t_cross);
  }
}

TEST_CASE("stop_when: a state dip of 1e-3 to 1e-9 below a level is found on the first swing",
          "[simulate_trust]") {
  // The tip of the pendulum released from horizontal reaches y = -1 at the bottom of its
  // first swing, at a quarter period; stop_when fires where it passes -1 + d, just before.
  const double k = 1.8540746773013719;  // K(1/2)
  const double quarter = std::sqrt((1.0 / 3) / (9.81 * 0.5)) * k;
  const double omega_bottom = std::sqrt(9.81 * 0.5 * 2 / (1.0 / 3));
  std::mt19937 rng(36);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 8; ++trial) {
    const double d = std::pow(10.0, -3 - 6 * u(rng));
    const double rtol = std::max(d / 100, 1e-14);
    const int steps = 1 + static_cast<int>(u(rng) * 300);
    CAPTURE(trial, d, rtol, steps);
    std::ostringstream params, r;
    params.precision(17);
    r.precision(17);
    params << ", d: " << d;
    r << rtol;
    const fs::path yaml = write_yaml("tip_dip", pendulum("-1 + d - tip.y", params.str()));
    const Run run =
        simulate(yaml, {"--t1", "3", "--steps", std::to_string(steps), "--rtol", r.str(), "-q"});
    INFO("stderr: " << run.r.err);
    REQUIRE(run.r.exit_code == 0);
    const double t = run.rows["t"].back();
    // On the first swing, before the bottom, by about acos(1 - d) / omega there.
    CHECK(t < quarter);
    CHECK(t == Approx(quarter - std::acos(1 - d) / omega_bottom).epsilon(1e-3));
    // At the crossing: tip.y = -1 + d to the tolerance.
    CHECK(std::abs(run.rows["tip.y"].back() - (-1 + d)) <= 10 * rtol);
  }
}

TEST_CASE("a non-finite stop_when names the item and its line, exit 1, the rows kept",
          "[simulate_trust]") {
  const fs::path yaml = write_yaml("nan_stop", pendulum("sqrt(0.05 - t) - 10"));
  const Run run = simulate(yaml, {"--t1", "0.1", "--steps", "10"});
  INFO("stderr: " << run.r.err);
  CHECK(run.r.exit_code == 1);
  CHECK(run.r.err.rfind("error: ", 0) == 0);
  CHECK(run.r.err.find("nan_stop.yaml:12: stop_when") != std::string::npos);
  CHECK(run.rows.rows() >= 1);
}

TEST_CASE("stop_when at t0: CVODE and --reference judge a value near 0 alike",
          "[simulate_trust]") {
  // The tip starts at height 0 and falls. tip.y + 1e-12 starts 1e-12 above 0, tip.y + 1e-6
  // far above its error bound; whatever each verdict, every method gives the same one (the
  // reference judged t0 by g > 0, CVODE by g > E).
  for (const char* offset : {"1e-12", "1e-6"}) {
    const fs::path yaml = write_yaml(std::string("t0_") + (offset[3] == '1' ? "near" : "above"),
                                     pendulum(std::string("tip.y + ") + offset));
    std::vector<std::size_t> rows;
    for (const std::vector<std::string>& method :
         {std::vector<std::string>{}, {"--method", "augmented"}, {"--reference", "16"}}) {
      std::vector<std::string> args{"--t1", "0.2", "--steps", "4"};
      args.insert(args.end(), method.begin(), method.end());
      const Run run = simulate(yaml, args);
      INFO(offset << " " << (method.empty() ? "minimal" : method[1]) << " stderr: " << run.r.err);
      CHECK(run.r.exit_code == 0);
      rows.push_back(run.rows.rows());
    }
    INFO(offset);
    CHECK(rows[1] == rows[0]);
    CHECK(rows[2] == rows[0]);
    if (std::string(offset) == "1e-6") CHECK(rows[0] == 1u);
    // 1e-12 is within the error bound (atol times |d tip.y / dq| and the scale: ~1e-10), which
    // needs stop_when's exact rate: without it (a realsymbol sliced into a symbol lost the
    // rate) the bound was rtol |g| alone and the run stopped at t0.
    if (std::string(offset) == "1e-12") CHECK(rows[0] == 5u);
  }
}

TEST_CASE("stop_when within its bound above 0 at t0 that then rises stops where it passes E",
          "[simulate_trust][stop_when]") {
  // A block sliding at a constant v: x = v t exactly. g = tip.x + d starts at d in (0, E0],
  // E0 = rtol d + atol scale_x (docs/format.md, stop_when: dg/dx = 1), so t0 is no stop; g
  // then rises and never goes below 0. Every method stops where g passes E0: at (E0 - d) / v,
  // chosen to be 0.3. (It ran to t1 before: monitoring started only once g < 0.)
  kc::SimulateOptions o;
  const auto text = [](double v, double d) {
    std::ostringstream y;
    y.precision(17);
    y << "name: slider\nparameters: {m: 1, v: " << v << ", d: " << d << "}\n"
      << "bodies:\n  - {name: block, q0: [0, 0, 0], mass: m}\n"
      << "joints:\n  - {type: translational, name: guide, i: ground, j: block, vi: [1, 0]}\n"
      << "free:\n  - {type: absolute_x, name: x, body: block, value0: 0, v0: v}\n"
      << "points:\n  - {name: tip, body: block, s: [0, 0]}\nstop_when: \"tip.x + d\"\n";
    return y.str();
  };
  kc::BuildOptions build;
  build.free_as_state = true;
  const double scale_x =
      kc::CompiledModel::from_mechanism(kc::parse_mechanism(text(1, 0), "slider.yaml"), {}, build)
          ->symbolic()
          .coordinate_scales[0];
  const double d = 0.5 * o.atol * scale_x;
  const double bound = o.rtol * d + o.atol * scale_x;
  const double v = (bound - d) / 0.3;
  const fs::path yaml = write_yaml("rises_within_bound", text(v, d));
  const auto model = kc::CompiledModel::from_file(yaml.string(), {}, build);
  const kc::ForceModel forces = kc::derive_forces(*model);
  for (const kc::Method method : {kc::Method::kMinimal, kc::Method::kAugmented}) {
    o.method = method;
    std::vector<double> times;
    const kc::SimulateSummary s = kc::run_simulation(
        *model, forces, {0, 1, 4},
        [&](const kc::SimulatedRow& row) { times.push_back(row.state.t); }, o);
    INFO("method " << static_cast<int>(method));
    CHECK(s.stopped);
    CHECK(s.stop_time == Approx(0.3).epsilon(1e-9));
    CHECK(s.stop_bound == Approx(bound).epsilon(1e-12));
    CHECK(times.back() == s.stop_time);
    CHECK(times.size() == 3u);  // t = 0, 0.25 and the stop
  }
  std::vector<double> times;
  const kc::ReferenceSimulationStats r = kc::run_reference_simulation(
      *model, forces, {0, 1, 4}, 20,
      [&](const kc::SimulatedRow& row) { times.push_back(row.state.t); }, {});
  CHECK(r.stopped);
  CHECK(r.stop_time == Approx(0.3).epsilon(1e-9));
  CHECK(times.size() == 3u);
  // The command line says so.
  const Run run = simulate(yaml, {"--t1", "1", "--steps", "4"});
  INFO("stderr: " << run.r.err);
  CHECK(run.r.exit_code == 0);
  CHECK(run.rows.rows() == 3u);
  CHECK(run.r.err.find("stopped at t = 0.3") != std::string::npos);
  CHECK(run.r.err.find("tip.x + d rose past its error bound at t0") != std::string::npos);
}

TEST_CASE("--reference refuses a stop_when that reads force columns, before any row",
          "[simulate_trust]") {
  // The reference has no rate for a force column, so nothing bounded its steps: on the cam it
  // stepped over the contact's first loss (t = 0.6159, which CVODE finds) and stopped at a
  // later crossing (0.6775) with exit 0.
  const fs::path dir = scratch("reference_force_stop");
  const fs::path out = dir / "out.csv";
  const CommandResult r =
      run_kinegen({"simulate", (fs::path(KINEGEN_SOURCE_DIR) / "examples/dynamics/cam_liftoff.yaml")
                                   .string(),
                   "--t1", "1", "--steps", "10", "--reference", "16", "-q", "-o", out.string()});
  INFO("stderr: " << r.err);
  CHECK(r.exit_code == 2);
  CHECK(r.err.rfind("error: ", 0) == 0);
  CHECK(r.err.find("cam_liftoff.yaml:52: stop_when: '-contact.fn' reads force columns") !=
        std::string::npos);
  CHECK(!fs::exists(out));
}

TEST_CASE("a driver's table that starts after t0 is named, not a free item's value0",
          "[simulate_trust]") {
  const fs::path dir = scratch("late_table");
  write_text(dir / "late.csv", "t,value\n0.5,0\n1,0.5\n2,0.7\n3,0.2\n");
  const fs::path yaml = dir / "late_table.yaml";
  write_text(yaml,
             "name: late_table\ngravity: [0, -9.81]\nbodies:\n"
             "  - {name: rod, q0: [0, 0, 0], mass: 1, inertia: 0.08, com: [0.5, 0]}\n"
             "  - {name: slide, q0: [0, 1, 0], mass: 1}\n"
             "joints:\n  - {type: revolute, name: pivot, i: ground, j: rod}\n"
             "  - {type: translational, name: rail, i: ground, j: slide, si: [0, 1], vi: [1, 0]}\n"
             "drivers:\n  - {type: absolute_x, body: slide, table: late.csv}\n"
             "free:\n  - {type: absolute_angle, name: theta, body: rod, value0: 0}\n");
  for (const char* method : {"minimal", "augmented"}) {
    const Run run = simulate(yaml, {"--t1", "2", "--steps", "4", "--method", method});
    INFO(method << " stderr: " << run.r.err);
    CHECK(run.r.exit_code == 2);
    CHECK(run.r.err.find("late_table.yaml:10: drivers[0] (absolute_x) table: table 'late.csv' "
                         "does not hold the start, t = 0 (its t runs from 0.5 to 3") !=
          std::string::npos);
    CHECK(run.r.err.find("value0") == std::string::npos);
    CHECK(run.rows.rows() == 0);
  }
}

// --- Tolerances, -v, and rows independent of the grid ----------------------------------------

TEST_CASE("tolerances outside the usable range are usage errors naming it", "[simulate_trust]") {
  const fs::path yaml = write_yaml("range", pendulum(""));
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"--rtol", "1e-20", "--atol", "1e-300"},
        std::vector<std::string>{"--rtol", "1e-20"}, std::vector<std::string>{"--atol", "1e-300"},
        std::vector<std::string>{"--rtol", "0.5"}}) {
    const Run run = simulate(yaml, [&] {
      std::vector<std::string> a{"--t1", "1", "--steps", "2"};
      a.insert(a.end(), args.begin(), args.end());
      return a;
    }());
    INFO("stderr: " << run.r.err);
    CHECK(run.r.exit_code == 2);
    CHECK(run.r.err.find("usable range") != std::string::npos);
    CHECK(std::count(run.r.err.begin(), run.r.err.end(), '\n') == 1);
  }
}

TEST_CASE("-v says what the run did: the integrator auto chose, its counts, the balance",
          "[simulate_trust]") {
  const fs::path yaml = write_yaml("verbose", oscillator(1e2, 1, 0.1));
  const Run run = simulate(yaml, {"--t1", "1", "--steps", "4", "-v"});
  INFO("stderr: " << run.r.err);
  REQUIRE(run.r.exit_code == 0);
  CHECK(run.r.err.find("integrator BDF (auto: the model has springs or dampers)") !=
        std::string::npos);
  CHECK(run.r.err.find(" steps, ") != std::string::npos);
  CHECK(run.r.err.find(" evaluations, ") != std::string::npos);
  CHECK(run.r.err.find(" error-test failures") != std::string::npos);
  CHECK(run.r.err.find("largest |energy.balance| ") != std::string::npos);
}

TEST_CASE("--rtol alone tightens a run: the double pendulum to 1e-9 rad at --rtol 1e-12",
          "[simulate_trust][release]") {
  // Against the 30-digit reference (extrapolation in CLN arithmetic). --atol follows --rtol
  // (1e-14 here); it used to stay at 1e-10 and hold the error at about 1e-7 rad.
  const fs::path yaml = write_yaml("double_pendulum", kDoublePendulum);
  const Run run = simulate(yaml, {"--t1", "2", "--steps", "4", "--rtol", "1e-12", "-q"});
  INFO("stderr: " << run.r.err);
  REQUIRE(run.r.exit_code == 0);
  const Table tight = run.rows;
  const Run ref = simulate(yaml, {"--t1", "2", "--steps", "4", "--reference", "30", "-q"});
  INFO("stderr: " << ref.r.err);
  REQUIRE(ref.r.exit_code == 0);
  for (const char* angle : {"a1", "a2"})
    for (std::size_t k = 0; k < tight.rows(); ++k) {
      CAPTURE(angle, k);
      CHECK(std::abs(tight[angle][k] - ref.rows[angle][k]) < 1e-9);
    }
}

TEST_CASE("rows do not depend on --steps: the same steps, the rows read off them",
          "[simulate_trust]") {
  // A chaotic motion amplifies any difference in the steps (a Newton start moved by a row's
  // evaluation grew to 8e-8 rad by t = 3): the rows between steps leave no trace, so the
  // steps are the same for every grid and each row is the dense output of the same step.
  const fs::path yaml = write_yaml("grid", kDoublePendulum);
  for (const char* method : {"minimal", "augmented"}) {
    CAPTURE(method);
    const Run coarse = simulate(yaml, {"--t1", "3", "--steps", "10", "--method", method, "-q"});
    const Run fine = simulate(yaml, {"--t1", "3", "--steps", "1000", "--method", method, "-q"});
    REQUIRE(coarse.r.exit_code == 0);
    REQUIRE(fine.r.exit_code == 0);
    for (std::size_t k = 0; k <= 10; ++k)
      for (const char* angle : {"a1", "a2"}) {
        CAPTURE(k, angle);
        REQUIRE(fine.rows["t"][100 * k] == Approx(coarse.rows["t"][k]));
        CHECK(fine.rows[angle][100 * k] == coarse.rows[angle][k]);
      }
  }
}
