// End-to-end tests of the dynamics examples (examples/dynamics/) through the kinegen
// binary, each against a truth the simulation does not compute itself:
// - energy: energy.balance at tight tolerances on the conservative examples; with dampers and
//   motors, energy.work against the power integrated from the CSV's own columns (Simpson), or
//   in closed form (a constant torque's work is torque times angle);
// - the motion fed back into `analyze --forces` (the free item given as an --input table, so a
//   prescribed driver) needs no effort on it: the effort falls as h^2 with the table's spacing
//   (its spline's error) and extrapolates to 0;
// - the cam's contact force against the follower's own equation of motion, and the run's stop
//   where it crosses 0; the four-bar's rest position as a static equilibrium and a minimum of
//   the potential; Andrews' squeezer's published initial angles and accelerations;
// - bad input: one `error:` line with the YAML line, exit 2, no file; a run that
//   fails in the middle keeps its rows and exits 1.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "support/files.hpp"
#include "support/run_command.hpp"

namespace {

namespace fs = std::filesystem;
using kinegen::test::read_text;
using kinegen::test::write_text;
using kinegen::test::CommandResult;

fs::path dynamics_example(const std::string& name) {
  return fs::path(KINEGEN_SOURCE_DIR) / "examples" / "dynamics" / (name + ".yaml");
}

fs::path scratch(const std::string& name) { return kinegen::test::scratch_dir("dynamics_examples", name); }

// `text` with its one occurrence of `from` replaced by `to`.
std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  REQUIRE(text.find(from, at + 1) == std::string::npos);
  return text.replace(at, from.size(), to);
}

// The 1-based line of `text` on which `what` starts.
int line_of(const std::string& text, const std::string& what) {
  const auto at = text.find(what);
  REQUIRE(at != std::string::npos);
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
}

CommandResult run_kinegen(const std::vector<std::string>& args) {
  std::vector<std::string> argv{KINEGEN_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  return kinegen::test::run_command(argv, {});
}

void require_one_error_line(const CommandResult& r) {
  INFO("stderr: " << r.err);
  REQUIRE(r.err.rfind("error: ", 0) == 0);
  REQUIRE(std::count(r.err.begin(), r.err.end(), '\n') == 1);
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
  std::istringstream in(read_text(path));
  Table t;
  std::string line, field;
  REQUIRE(std::getline(in, line));
  std::istringstream header(line);
  while (std::getline(header, field, ',')) t.names.push_back(field);
  t.columns.resize(t.names.size());
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::size_t k = 0;
    for (; k < t.names.size() && std::getline(row, field, ','); ++k)
      t.columns[k].push_back(std::stod(field));
    REQUIRE(k == t.names.size());
    REQUIRE_FALSE(std::getline(row, field, ','));
  }
  return t;
}

// `kinegen simulate` of an example (or of any file) into dir/out.csv; it must succeed.
Table simulate(const fs::path& yaml, const fs::path& out, std::vector<std::string> args) {
  std::vector<std::string> argv{"simulate", yaml.string(), "-o", out.string()};
  argv.insert(argv.end(), args.begin(), args.end());
  const CommandResult r = run_kinegen(argv);
  INFO("stderr: " << r.err);
  REQUIRE(r.exit_code == 0);
  return read_csv(out);
}

double max_abs(const std::vector<double>& v, std::size_t from = 0, std::size_t to = SIZE_MAX) {
  double m = 0;
  for (std::size_t k = from; k < std::min(to, v.size()); ++k) m = std::max(m, std::abs(v[k]));
  return m;
}

double spread(const std::vector<double>& v) {
  return *std::max_element(v.begin(), v.end()) - *std::min_element(v.begin(), v.end());
}

// The energy the run exchanges: the largest kinetic energy, work and change of potential.
double energy_scale(const Table& s) {
  return std::max({max_abs(s["energy.kinetic"]), max_abs(s["energy.work"]),
                   spread(s["energy.potential"])});
}

// Composite Simpson over the first `rows` rows (an odd count) of a uniform grid.
double simpson(const std::vector<double>& t, const std::vector<double>& f, std::size_t rows) {
  REQUIRE(rows % 2 == 1);
  const double h = t[1] - t[0];
  double sum = f[0] + f[rows - 1];
  for (std::size_t k = 1; k + 1 < rows; ++k) sum += (k % 2 ? 4 : 2) * f[k];
  return h / 3 * sum;
}

// The 3-4-5 law, clamped.
double poly345(double x) {
  if (x <= 0) return 0;
  if (x >= 1) return 1;
  return x * x * x * (10 - 15 * x + 6 * x * x);
}

const std::vector<std::string> kTight = {"--rtol", "1e-12", "--atol", "1e-14"};

std::vector<std::string> with(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

}  // namespace

TEST_CASE("dynamics examples: conservative runs keep energy.balance below 1e-8 of the energy",
          "[dynamics_examples]") {
  struct Case {
    std::string example, t1;
    std::vector<std::string> params;
  };
  // The pendulum; the four-bar without its damper; the cam without its motor, swinging under
  // the spring's push on it (springs and gravity only, so energy.work stays 0).
  const std::vector<Case> cases = {{"pendulum", "10", {}},
                                   {"four_bar_damped", "10", {"--param", "damping=0"}},
                                   {"cam_liftoff", "5", {"--param", "T0=0"}}};
  const fs::path dir = scratch("conservative");
  for (const Case& c : cases) {
    INFO(c.example);
    const Table s = simulate(dynamics_example(c.example), dir / (c.example + ".csv"),
                             with(with({"--t1", c.t1, "--steps", "500"}, kTight), c.params));
    const double scale = energy_scale(s);
    // No load does work; what is left is rounding that the integrator's linear algebra
    // carries into the work's state from the others (5.5e-27 J on the four-bar).
    REQUIRE(max_abs(s["energy.work"]) <= 1e-15 * scale);
    // A real exchange between kinetic and potential energy, not a mechanism at rest.
    REQUIRE(max_abs(s["energy.kinetic"]) > 0.5 * spread(s["energy.potential"]));
    REQUIRE(scale > 0);
    CHECK(max_abs(s["energy.balance"]) < 1e-8 * scale);
  }
}

TEST_CASE("dynamics examples: with dampers and motors the work is the energy gained or lost",
          "[dynamics_examples]") {
  const fs::path dir = scratch("power");
  SECTION("the four-bar's damper takes out what it loses; integrated from its columns") {
    const Table s = simulate(dynamics_example("four_bar_damped"), dir / "four_bar.csv",
                             with({"--t1", "20", "--steps", "4000"}, kTight));
    const std::size_t n = s.rows();
    const double lost = s["energy.kinetic"][0] + s["energy.potential"][0] -
                        s["energy.kinetic"][n - 1] - s["energy.potential"][n - 1];
    REQUIRE(lost > 1);  // J: most of its potential energy
    CHECK(max_abs(s["energy.balance"]) < 1e-8 * lost);
    CHECK(std::abs(s["energy.work"][n - 1] + lost) < 1e-8 * lost);
    // The damper's power, -c omega_rocker^2 (c = 0.5 N m s), from the CSV.
    std::vector<double> power;
    for (double w : s["rocker.omega"]) power.push_back(-0.5 * w * w);
    CHECK(std::abs(simpson(s["t"], power, n) - s["energy.work"][n - 1]) < 1e-7 * lost);
    // It settles: at 20 s the motion has all but stopped.
    CHECK(s["energy.kinetic"][n - 1] < 1e-9 * lost);
  }
  SECTION("the press: motor and forming work from the columns, the flywheel slowing") {
    const Table s = simulate(dynamics_example("press_flywheel"), dir / "press.csv",
                             with({"--t1", "6", "--steps", "12000"}, kTight));
    const std::size_t n = s.rows();
    const double work = s["energy.work"][n - 1];
    REQUIRE(work > 100);  // J
    CHECK(max_abs(s["energy.balance"]) < 1e-8 * energy_scale(s));
    // The file's parameters: T0 = 200 N m, omega0 = 7 rad/s; F = 5000 N from r + l - contact
    // = 0.23 m, ramp 2 mm, fading below vs = 0.02 m/s.
    std::vector<double> power, motor;
    for (std::size_t k = 0; k < n; ++k) {
      const double w = s["crank.omega"][k], x = s["ram.x"][k], v = s["ram.vx"][k];
      const double fx = -5000 * poly345((x - 0.23) / 0.002) * poly345(v / 0.02);
      motor.push_back(200 * (1 - w / 7) * w);
      power.push_back(motor.back() + fx * v);
    }
    const double forming = simpson(s["t"], power, n) - simpson(s["t"], motor, n);
    REQUIRE(forming < -300);  // J: several forming strokes
    CHECK(std::abs(simpson(s["t"], power, n) - work) < 1e-5 * std::abs(forming));
    // The speed drops at each forming stroke: the crank's speed has a local minimum within
    // each stroke's forming window, below its running maximum by more than 5%.
    const auto& w = s["crank.omega"];
    int drops = 0;
    double running_max = 0;
    bool dropped = false;
    for (std::size_t k = 0; k < n; ++k) {
      running_max = std::max(running_max, w[k]);
      if (!dropped && w[k] < 0.95 * running_max && s["ram.x"][k] > 0.23) {
        ++drops;
        dropped = true;
      }
      if (s["ram.x"][k] < 0.2) dropped = false, running_max = w[k];
    }
    CHECK(drops >= 5);
  }
  SECTION("Andrews' squeezer: the constant motor torque's work is torque times angle") {
    const Table s = simulate(dynamics_example("andrews"), dir / "andrews.csv",
                             with({"--t1", "0.03", "--steps", "300"}, kTight));
    const std::size_t n = s.rows();
    const double work = 0.033 * (s["beta"][n - 1] - s["beta"][0]);
    REQUIRE(work > 0.3);  // J, over two and a half turns
    CHECK(std::abs(s["energy.work"][n - 1] - work) < 1e-9 * work);
    CHECK(max_abs(s["energy.balance"]) < 1e-8 * energy_scale(s));
  }
  SECTION("the cam's motor runs it up: its work from the columns") {
    const Table s = simulate(dynamics_example("cam_liftoff"), dir / "cam.csv",
                             with({"--t1", "0.6", "--steps", "1200"}, kTight));
    const std::size_t n = s.rows();
    REQUIRE(n == 1201);  // no lift-off yet
    std::vector<double> power;
    for (double w : s["cam.omega"]) power.push_back(0.5 * (1 - w / 150) * w);
    const double work = s["energy.work"][n - 1];
    REQUIRE(work > 5);  // J
    CHECK(std::abs(simpson(s["t"], power, n) - work) < 1e-8 * work);
    CHECK(max_abs(s["energy.balance"]) < 1e-8 * energy_scale(s));
  }
}

TEST_CASE("dynamics examples: the simulated motion fed back into analyze --forces needs no "
          "effort on the free item",
          "[dynamics_examples]") {
  struct Case {
    std::string example, z, t1;
    int steps;
    double extrapolated;  // the bound on the extrapolated effort, relative to the scale
  };
  // The press's forming law is C2 only (3-4-5 pieces), so the table spline's error has a
  // jumping h^4 term there and extrapolates less far.
  // The pendulum at 3e-7: its rows carry CVODE's error at rtol 1e-13 (theta to 4.6e-12 of the
  // 20-digit reference), which the spline's second derivative amplifies by 1/h^2.
  const std::vector<Case> cases = {{"pendulum", "theta", "2", 2000, 3e-7},
                                   {"four_bar_damped", "theta", "5", 5000, 1e-6},
                                   {"press_flywheel", "theta", "3", 6000, 2e-4},
                                   {"cam_liftoff", "theta", "0.6", 600, 1e-6},
                                   {"andrews", "beta", "0.03", 3000, 1e-6}};
  for (const Case& c : cases) {
    INFO(c.example);
    const fs::path dir = scratch("feedback_" + c.example);
    std::vector<std::vector<double>> effort;
    double scale = 0;
    for (int steps : {c.steps, 2 * c.steps}) {
      const std::string n = std::to_string(steps);
      const Table s = simulate(dynamics_example(c.example), dir / ("sim" + n + ".csv"),
                               with({"--t1", c.t1, "--steps", n}, {"--rtol", "1e-13", "--atol",
                                                                   "1e-15"}));
      REQUIRE(s.rows() == static_cast<std::size_t>(steps + 1));
      // The free coordinate as a table (t,value), then prescribed by analyze.
      std::ostringstream table;
      table.precision(17);
      table << "t,value\n";
      for (std::size_t k = 0; k < s.rows(); ++k)
        table << s["t"][k] << "," << s[c.z][k] << "\n";
      write_text(dir / ("z" + n + ".csv"), table.str());
      const CommandResult r =
          run_kinegen({"analyze", dynamics_example(c.example).string(), "--t0", "0", "--t1", c.t1,
                   "--steps", n, "--forces", "--input",
                   c.z + "=" + (dir / ("z" + n + ".csv")).string(), "-o",
                   (dir / ("an" + n + ".csv")).string()});
      INFO("stderr: " << r.err);
      REQUIRE(r.exit_code == 0);
      const Table a = read_csv(dir / ("an" + n + ".csv"));
      effort.push_back(a[c.z + ".effort"]);
      // The scale of the generalized force on z: the reduced mass (2 T / zd^2, one degree of
      // freedom) times the acceleration, at its largest.
      const auto &zd = s[c.z + ".v"], &zdd = s[c.z + ".a"], &kinetic = s["energy.kinetic"];
      for (std::size_t k = 0; k < s.rows(); ++k)
        if (std::abs(zd[k]) > 1e-3 * max_abs(zd))
          scale = std::max(scale, 2 * kinetic[k] / (zd[k] * zd[k]) * std::abs(zdd[k]));
    }
    REQUIRE(scale > 0);
    // The table's ends (not-a-knot) are left out: 5% at either end.
    const std::size_t m = effort[0].size(), lo = m / 20, hi = m - m / 20;
    const double coarse = max_abs(effort[0], lo, hi), fine = max_abs(effort[1], 2 * lo, 2 * hi);
    INFO("coarse " << coarse / scale << ", fine " << fine / scale);
    CHECK(fine < 1e-3 * scale);
    // Halving the spacing quarters it: what is left is the spline's error, not the model's.
    CHECK(coarse / fine > 3.5);
    CHECK(coarse / fine < 4.5);
    double extrapolated = 0;
    for (std::size_t k = lo; k < hi; ++k)
      extrapolated = std::max(extrapolated, std::abs(4 * effort[1][2 * k] - effort[0][k]) / 3);
    INFO("extrapolated " << extrapolated / scale);
    CHECK(extrapolated < c.extrapolated * scale);
  }
}

TEST_CASE("dynamics examples: the cam run stops where the contact force crosses zero",
          "[dynamics_examples]") {
  const fs::path dir = scratch("cam_stop");
  const Table s = simulate(dynamics_example("cam_liftoff"), dir / "cam.csv",
                           with({"--t1", "5", "--steps", "500", "--forces"}, kTight));
  const std::size_t n = s.rows();
  REQUIRE(n >= 3);
  REQUIRE(n < 501);
  const auto& t = s["t"];
  const auto& fn = s["contact.fn"];
  // One more row at the root, off the grid (0.01 s apart), after the last grid row.
  REQUIRE(t[n - 1] > t[n - 2]);
  REQUIRE(t[n - 1] - t[n - 2] < 0.01);
  const double peak = max_abs(fn);
  for (std::size_t k = 0; k + 1 < n; ++k) REQUIRE(fn[k] > 0);
  CHECK(std::abs(fn[n - 1]) < 1e-9 * peak);
  // The follower's own equation of motion: the contact pushes it up with fn against its
  // weight and the spring (k = 500 N/m, anchor H = 0.1 m, free length L0 = 0.09 m, m = 0.2 kg):
  // m ay = fn - m g - k (L0 - (H - y)).
  double worst = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double y = s["follower.y"][k], ay = s["follower.ay"][k];
    const double expected = 0.2 * (ay + 9.81) + 500 * (0.09 - (0.1 - y));
    worst = std::max(worst, std::abs(fn[k] - expected));
  }
  CHECK(worst < 1e-9 * peak);
}

TEST_CASE("dynamics examples: the four-bar comes to rest at a minimum of its potential",
          "[dynamics_examples]") {
  const fs::path dir = scratch("four_bar_rest");
  const Table s = simulate(dynamics_example("four_bar_damped"), dir / "run.csv",
                           with({"--t1", "20", "--steps", "200"}, kTight));
  const double rest = s["theta"].back();
  // Held there (a constant table), it needs no torque: a static equilibrium.
  write_text(dir / "rest.csv", "t,value\n0," + std::to_string(rest) + "\n1," +
                                   std::to_string(rest) + "\n2," + std::to_string(rest) +
                                   "\n3," + std::to_string(rest) + "\n");
  const CommandResult r = run_kinegen({"analyze", dynamics_example("four_bar_damped").string(),
                                   "--t0", "0", "--t1", "3", "--steps", "3", "--forces",
                                   "--input", "theta=" + (dir / "rest.csv").string(), "-o",
                                   (dir / "rest_forces.csv").string()});
  INFO("stderr: " << r.err);
  REQUIRE(r.exit_code == 0);
  const Table a = read_csv(dir / "rest_forces.csv");
  // Against the largest gravity torque about the crank that its own weight alone gives.
  const double weight_torque = 0.4 * 9.81 * 0.05;
  // std::to_string keeps 6 decimals: the held angle is within 5e-7 of the rest.
  CHECK(max_abs(a["theta.effort"]) < 1e-3 * weight_torque);
  // A minimum, not a maximum: released beside it, the potential is higher on both sides.
  for (double offset : {-0.05, 0.05}) {
    const Table near = simulate(
        dynamics_example("four_bar_damped"), dir / "near.csv",
        {"--t1", "1e-6", "--steps", "1", "--param", "theta0=" + std::to_string(rest + offset)});
    CHECK(near["energy.potential"][0] > s["energy.potential"].back());
  }
}

TEST_CASE("dynamics examples: Andrews' squeezer assembles at the published initial state",
          "[dynamics_examples]") {
  // The problem's published initial values (Hairer and Wanner II, VII.7; the IVP test set):
  // with beta0 and Theta = 0 the other angles follow from the assembly, and the consistent
  // initial accelerations from the equations of motion, which the Cartesian model must give.
  const fs::path dir = scratch("andrews_initial");
  const Table s = simulate(dynamics_example("andrews"), dir / "start.csv",
                           with({"--t1", "1e-6", "--steps", "1"}, kTight));
  const std::map<std::string, double> angles = {{"Theta", 0},
                                                {"gamma", 0.455279819163070380255912382449},
                                                {"Phi", 0.222668390165885884674473185609},
                                                {"delta", 0.487364979543842550225598953530},
                                                {"Omega", -0.222668390165885884674473185609},
                                                {"epsilon", 1.23054744454982119249735015568}};
  for (const auto& [name, value] : angles) {
    INFO(name);
    CHECK(std::abs(s[name][0] - value) < 1e-13);
  }
  CHECK(std::abs(s["beta.a"][0] - 14222.4439199541138705911625887) < 1e-9 * 14222.44);
  CHECK(std::abs(s["Theta.a"][0] - -10666.8329399655854029433719415) < 1e-9 * 14222.44);
}

TEST_CASE("dynamics examples: bad free items and simulate options are one error line, exit 2",
          "[dynamics_examples]") {
  const fs::path dir = scratch("bad_input");
  const std::string pendulum = read_text(dynamics_example("pendulum"));
  const std::string four_bar = read_text(dynamics_example("four_bar_damped"));
  const std::string free_line = "  - {type: absolute_angle, name: theta, body: crank";
  struct Case {
    std::string what, text;
    std::vector<std::string> args;
    std::string expected;  // in the message
    int line;              // of the YAML, 0: a command-line error
  };
  std::vector<Case> cases;
  {
    const std::string t =
        replaced(pendulum, "    name: theta\n    body: rod", "    name: theta\n    body: nobody");
    cases.push_back({"a free item on a missing body", t, {}, "unknown body 'nobody'",
                     line_of(t, "    body: nobody")});
  }
  {
    const std::string t =
        replaced(four_bar, free_line, "  - {type: absolute_angle, name: psi, body: rocker}\n" +
                                          free_line);
    cases.push_back({"too many free items", t, {}, "1 degree of freedom",
                     line_of(t, "  - {type: absolute_angle, name: psi")});
  }
  {
    const std::string t =
        replaced(four_bar, "  - {type: revolute, name: B, i: coupler, j: rocker, si: [b, 0], "
                           "sj: [c, 0]}\n",
                 "");
    cases.push_back({"too few free items", t, {}, "3 degrees of freedom", line_of(t, free_line)});
  }
  {
    const std::string t = replaced(pendulum,
                                   "  - type: absolute_angle\n    name: theta\n    body: rod\n"
                                   "    value0: 0\n",
                                   "  - type: absolute_x\n    name: pivot_x\n    body: rod\n");
    cases.push_back({"a free item that adds nothing to the rank", t, {}, "adds nothing",
                     line_of(t, "  - type: absolute_x")});
  }
  cases.push_back({"a massless free coordinate", pendulum, {"--param", "m=0"},
                   "carries no inertia", line_of(pendulum, "  - type: absolute_angle")});
  {
    // The rocker of this crank-rocker swings between about 1.5 and 2.6 rad: never at 3.
    const std::string t = replaced(four_bar, free_line + ", value0: theta0, v0: 0}",
                                   "  - {type: absolute_angle, name: psi, body: rocker, "
                                   "value0: 3, v0: 0}");
    cases.push_back({"value0 where the mechanism does not assemble", t, {}, "does not assemble",
                     line_of(t, "name: psi")});
  }
  {
    const std::string t = four_bar + "stop_when: \"-nothing.fn\"\n";
    cases.push_back({"a stop_when with an unknown name", t, {}, "'nothing.fn'",
                     line_of(t, "stop_when:")});
  }
  cases.push_back({"--t1 before --t0", pendulum, {"--t0", "2"}, "--t1", 0});
  cases.push_back({"a NaN rtol", pendulum, {"--rtol", "nan"}, "--rtol", 0});
  cases.push_back({"an infinite rtol", pendulum, {"--rtol", "inf"}, "--rtol", 0});
  cases.push_back({"an infinite atol", pendulum, {"--atol", "inf"}, "--atol", 0});
  cases.push_back({"a NaN atol", pendulum, {"--atol", "nan"}, "--atol", 0});
  for (const Case& c : cases) {
    INFO(c.what);
    const fs::path yaml = dir / "bad.yaml", out = dir / "out.csv";
    fs::remove(out);
    write_text(yaml, c.text);
    const CommandResult r = run_kinegen(with(
        {"simulate", yaml.string(), "--t1", "1", "--steps", "10", "-o", out.string()}, c.args));
    INFO("stderr: " << r.err);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.err.find(c.expected) != std::string::npos);
    if (c.line > 0)
      CHECK(r.err.rfind("error: " + yaml.string() + ":" + std::to_string(c.line) + ":", 0) == 0);
    CHECK_FALSE(fs::exists(out));
  }
}

TEST_CASE("dynamics examples: a run that fails in the middle keeps its rows and exits 1",
          "[dynamics_examples]") {
  // The press moved by its ram (the free item its x) from mid-stroke towards the front dead
  // centre, with no motor and no workpiece: there x stops determining the crank angle, which
  // the minimal coordinates cannot pass.
  const fs::path dir = scratch("mid_run");
  std::string t = read_text(dynamics_example("press_flywheel"));
  t = replaced(t, "{type: absolute_angle, name: theta, body: crank, value0: pi, v0: 0}",
               "{type: absolute_x, name: stroke, body: ram, value0: 0.2, v0: 0.5}");
  t = replaced(t, "q0: [0, 0, 3.14159]", "q0: [0, 0, 1.45]");
  t = replaced(t, "q0: [-0.05, 0, 0]", "q0: [0.006, 0.05, -0.25]");
  t = replaced(t, "q0: [0.15, 0, 0]", "q0: [0.2, 0, 0]");
  write_text(dir / "ram_driven.yaml", t);
  const fs::path out = dir / "out.csv";
  const CommandResult r =
      run_kinegen({"simulate", (dir / "ram_driven.yaml").string(), "--t1", "1", "--steps", "100",
               "--param", "T0=0", "--param", "F=0", "-o", out.string()});
  INFO("stderr: " << r.err);
  CHECK(r.exit_code == 1);
  require_one_error_line(r);
  CHECK(r.err.find("--method augmented") != std::string::npos);
  const auto at = r.err.find("failed at t = ");
  REQUIRE(at != std::string::npos);
  const double failed_at = std::stod(r.err.substr(at + 14));
  REQUIRE(fs::exists(out));
  const Table s = read_csv(out);
  REQUIRE(s.rows() > 5);
  CHECK(s["t"].back() < failed_at);
  CHECK(failed_at < 1);
  // The rows kept are good ones: the ram short of the dead centre, the energy balanced.
  CHECK(s["ram.x"].back() < 0.25);
  CHECK(max_abs(s["energy.balance"]) < 1e-3 * max_abs(s["energy.kinetic"]));
}

TEST_CASE("dynamics examples: the minimal coordinates stop at the N-four-bar's flat position",
          "[dynamics_examples]") {
  // The N-four-bar of the IFToMM benchmark A02 (N = 8): falling from 45 degrees it reaches
  // the flat position, where Phi_q loses N ranks, after 0.29 s. The default method cannot
  // pass it: exit 1, the rows so far kept, the constraints and the other method named (it
  // used to retry there for ever, the step shrinking below the ulps of t).
  const int n = 8;
  std::ostringstream y;
  y.precision(17);
  y << "name: n_four_bar\nparameters: {m: 1.0, l: 1.0, g: 9.81}\ngravity: [0, -g]\nbodies:\n";
  for (int k = 0; k <= n; ++k)
    y << "  - {name: crank_" << k << ", q0: [" << k << ", 0, 0.7853981633974483], mass: m, "
      << "inertia: \"m*l^2/12\", com: [\"l/2\", 0]}\n";
  for (int k = 0; k < n; ++k)
    y << "  - {name: coupler_" << k << ", q0: [" << k + std::sqrt(0.5) << ", "
      << std::sqrt(0.5) << ", 0], mass: m, inertia: \"m*l^2/12\", com: [\"l/2\", 0]}\n";
  y << "joints:\n";
  for (int k = 0; k <= n; ++k)
    y << "  - {type: revolute, name: O" << k << ", i: ground, j: crank_" << k << ", si: ["
      << k << ", 0]}\n";
  for (int k = 0; k < n; ++k)
    y << "  - {type: revolute, name: A" << k << ", i: crank_" << k << ", j: coupler_" << k
      << ", si: [l, 0]}\n  - {type: revolute, name: B" << k << ", i: coupler_" << k
      << ", j: crank_" << k + 1 << ", si: [l, 0], sj: [l, 0]}\n";
  y << "free:\n  - {type: absolute_angle, name: theta, body: crank_0, value0: \"pi/4\", "
       "v0: \"-sqrt(2)\"}\n";
  const fs::path dir = scratch("flat_position");
  write_text(dir / "n_four_bar.yaml", y.str());
  const fs::path out = dir / "out.csv";
  const CommandResult r = run_kinegen({"simulate", (dir / "n_four_bar.yaml").string(), "--t1",
                                       "20", "--steps", "2000", "-o", out.string()});
  INFO("stderr: " << r.err);
  CHECK(r.exit_code == 1);
  require_one_error_line(r);
  CHECK(r.err.find("--method augmented") != std::string::npos);
  CHECK(r.err.find("involved: ") != std::string::npos);
  const auto at = r.err.find("failed at t = ");
  REQUIRE(at != std::string::npos);
  const double failed_at = std::stod(r.err.substr(at + 14));
  CHECK(failed_at > 0.28);
  CHECK(failed_at < 0.30);
  const Table s = read_csv(out);
  REQUIRE(s.rows() > 20);
  CHECK(s["t"].back() < failed_at);
  CHECK(s["theta"].back() > 0);  // short of the flat position, on the branch it started on
}
