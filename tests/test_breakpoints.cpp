// The breakpoints of a simulation (analysis/breakpoints.hpp) against times computed by hand:
// piece boundaries and period seams, clamped laws' ends with linear and nonlinear arguments,
// the knots of driver tables (plain and periodic), of input tables and of load input tables,
// and none where a law's argument depends on the state.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/breakpoints.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "support/run_command.hpp"

namespace {

namespace kc = kinegen::codegen;
namespace fs = std::filesystem;

fs::path folder() {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "breakpoints";
  fs::create_directories(dir);
  return dir;
}

std::string write(const std::string& name, const std::string& text) {
  const fs::path p = folder() / name;
  std::ofstream(p) << text;
  return p.string();
}

// A crank driven by `driver` (the rest of its list entry), with `forces` (a YAML list or "").
std::string crank(const std::string& name, const std::string& driver,
                  const std::string& forces = "") {
  std::string text = "name: " + name +
                     "\n"
                     "parameters: {T: 2, a: 0.5, tau: 3}\n"
                     "bodies:\n"
                     "  - {name: crank, q0: [0, 0, 0], inertia: 1}\n"
                     "joints:\n"
                     "  - {type: revolute, name: pin, i: ground, j: crank}\n"
                     "drivers:\n"
                     "  - {type: absolute_angle, name: motor, body: crank, " +
                     driver + "}\n";
  if (!forces.empty()) text += "forces:\n" + forces;
  return write(name + ".yaml", text);
}

void check_times(const std::vector<double>& got, const std::vector<double>& want) {
  INFO("got " << got.size() << " times, want " << want.size());
  REQUIRE(got.size() == want.size());
  for (std::size_t k = 0; k < want.size(); ++k) {
    INFO("breakpoint " << k << ": " << got[k] << " for " << want[k]);
    CHECK(std::abs(got[k] - want[k]) <= 4e-15 * std::max(1.0, std::abs(want[k])));
  }
}

}  // namespace

TEST_CASE("breakpoints: piece boundaries, period seams and a law's ends in a periodic law",
          "[breakpoints]") {
  // On [0, T) = [0, 2): 0 until a = 0.5, then poly345((t - a)/1) until 1.5, then 1; each period
  // adds 1. Kinks at a + 2k (boundary, law at 0), 1.5 + 2k (boundary, law at 1), 2k (seams).
  const auto model = kc::CompiledModel::from_file(crank(
      "periodic_pieces",
      "period: T, f: [{until: a, f: \"0\"}, {until: 1.5, f: \"poly345((t - a)/1)\"}, {f: \"1\"}]"));
  check_times(kc::breakpoints(*model, 0, 5), {0.5, 1.5, 2, 2.5, 3.5, 4, 4.5});
  // Strictly inside (t0, t1): the ends are not breakpoints.
  check_times(kc::breakpoints(*model, 0.5, 4.5), {1.5, 2, 2.5, 3.5, 4});
  check_times(kc::breakpoints(*model, -1, 0.25), {-0.5, 0});  // the period before t = 0 too
  CHECK(kc::breakpoints(*model, 0.6, 1.4).empty());
  // A parameter override moves them.
  const auto moved = kc::CompiledModel::from_file(model->mechanism().source, {{"a", "0.25"}});
  check_times(kc::breakpoints(*moved, 0, 2.1), {0.25, 1.25, 1.5, 2});  // the law ends at a + 1
}

TEST_CASE("breakpoints: laws of a load, with linear and nonlinear arguments", "[breakpoints]") {
  // harmonic(t^2/2) reaches 1 at sqrt(2) (sampled and bisected); cycloidal(2 sin(t)) leaves 0
  // at 0 (t0), reaches 1 at pi/6 and leaves it at 5 pi/6, and is 0 again from pi to 2 pi;
  // poly4567(t/tau - 1) starts at tau = 3 and ends at 2 tau = 6.
  const double pi = std::acos(-1.0);
  const auto model = kc::CompiledModel::from_file(crank(
      "load_laws", "f: \"t\"",
      "  - {type: torque, name: a, body: crank, value: \"harmonic(t^2/2) + cycloidal(2*sin(t))\"}\n"
      "  - {type: torque, name: b, body: crank, value: \"poly4567(t/tau - 1)\"}\n"));
  check_times(kc::breakpoints(*model, 0, 7),
              {pi / 6, std::sqrt(2.0), 5 * pi / 6, 3, pi, 6, 2 * pi, 13 * pi / 6});
}

TEST_CASE("breakpoints: a linear argument with pi in it is located exactly, not skipped",
          "[breakpoints]") {
  // poly345(t/pi - 1) starts at t = pi and ends at 2 pi; harmonic((t - pi/2)*2) spans
  // pi/2 .. pi/2 + 1/2. A coefficient holding pi is a number, not a reason to skip the law.
  const double pi = std::acos(-1.0);
  const auto model = kc::CompiledModel::from_file(crank(
      "pi_laws", "f: \"t\"",
      "  - {type: torque, name: a, body: crank, value: \"poly345(t/pi - 1)\"}\n"
      "  - {type: torque, name: b, body: crank, value: \"harmonic((t - pi/2)*2)\"}\n"));
  check_times(kc::breakpoints(*model, 0, 7), {pi / 2, pi / 2 + 0.5, pi, 2 * pi});
}

TEST_CASE("breakpoints: the knots of driver tables, plain and periodic", "[breakpoints]") {
  write("plain.csv", "t,value\n0,0\n0.3,0.1\n0.7,0.2\n1.2,0.5\n2,0.6\n");
  const auto plain = kc::CompiledModel::from_file(crank("plain_table", "table: plain.csv"));
  check_times(kc::breakpoints(*plain, 0, 2), {0.3, 0.7, 1.2});
  check_times(kc::breakpoints(*plain, 0.5, 1.5), {0.7, 1.2});
  write("periodic.csv", "t,value\n0,0\n0.25,0.1\n0.6,0.2\n1,1\n");
  const auto periodic =
      kc::CompiledModel::from_file(crank("periodic_table", "period: 1, table: periodic.csv"));
  check_times(kc::breakpoints(*periodic, 0, 2.5), {0.25, 0.6, 1, 1.25, 1.6, 2, 2.25});
}

TEST_CASE("breakpoints: the knots of input tables, a driver's and a load's", "[breakpoints]") {
  const std::string table = write("input.csv", "t,value\n-1,0\n0.5,0.1\n0.8,0.2\n3,0.5\n");
  kc::BuildOptions build;
  build.inputs = {{"motor", table}};
  build.inputs_required = true;
  const auto driver = kc::CompiledModel::from_file(crank("input_driver", "f: input"), {}, build);
  check_times(kc::breakpoints(*driver, 0, 3), {0.5, 0.8});
  // The cart-pole's push is a load input (push_x).
  kc::BuildOptions load;
  load.free_as_state = true;
  load.inputs = {{"push_x", table}};
  load.inputs_required = true;
  const auto cart = kc::CompiledModel::from_file(
      (fs::path(KINEGEN_SOURCE_DIR) / "examples/dynamics/cart_pole.yaml").string(), {}, load);
  check_times(kc::breakpoints(*cart, -0.5, 1), {0.5, 0.8});
}

TEST_CASE("breakpoints: a law of the state is an event, not a breakpoint", "[breakpoints]") {
  // The press's forming force is poly345 of the ram's depth and speed: state-dependent.
  kc::BuildOptions build;
  build.free_as_state = true;
  const auto press = kc::CompiledModel::from_file(
      (fs::path(KINEGEN_SOURCE_DIR) / "examples/dynamics/press_flywheel.yaml").string(), {}, build);
  CHECK(kc::breakpoints(*press, 0, 3).empty());
  // Its two switches: depth/ramp and xd_ram/vs, each at 0 and 1.
  const auto switches = kc::state_switches(*press, kc::derive_forces(*press));
  REQUIRE(switches.size() == 2);
  for (const auto& s : switches) {
    CHECK(s.levels.base == std::vector<double>{0, 1});
    CHECK(s.levels.period == 0);
  }
}

TEST_CASE("breakpoints: far more periods than a run can restart at is refused", "[breakpoints]") {
  const auto model = kc::CompiledModel::from_file(
      crank("tiny_period", "period: 1e-6, f: [{until: 5e-7, f: \"t\"}, {f: \"1e-6 - t\"}]"));
  CHECK(kc::breakpoints(*model, 0, 1e-4).size() == 199);
  CHECK_THROWS_AS(kc::breakpoints(*model, 0, 10), kc::UsageError);
}

// ---------------------------------------------------------------------------------------------
// Input tables (docs/format.md, Simulation: inputs): one that does not cover the run is a usage
// error before it; the rows inside a table's range are written when the run fails after it; no
// row holds a non-finite value.

namespace {

std::string example(const std::string& name) {
  return (fs::path(KINEGEN_SOURCE_DIR) / "examples" / name).string();
}

int lines(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

}  // namespace

TEST_CASE("simulate: an input table that does not cover the run is refused before it",
          "[breakpoints][cli]") {
  const std::string early = write("push_early.csv", "t,value\n0,0\n0.2,0\n0.4,0\n0.6,0\n");
  const std::string late = write("push_late.csv", "t,value\n0.1,0\n0.5,0\n0.8,0\n1.2,0\n");
  for (const std::string& table : {early, late}) {
    for (const char* digits : {"", "20"}) {
      std::vector<std::string> argv{KINEGEN_EXE, "simulate", example("dynamics/cart_pole.yaml"),
                                    "--t1",      "1",        "--steps",
                                    "10",        "--input",  "push_x=" + table};
      if (*digits) argv.insert(argv.end(), {"--reference", digits});
      const auto r = kinegen::test::run_command(argv);
      INFO(r.err);
      CHECK(r.exit_code == 2);
      CHECK(r.out.empty());
      CHECK(r.err.rfind("error: ", 0) == 0);
      CHECK(r.err.find("--input push_x=" + table + ": the table covers t = ") != std::string::npos);
      CHECK(r.err.find(", the run t = 0 to 1") != std::string::npos);
    }
  }
}

TEST_CASE("a table that ends inside the run: the reference writes every row before its end",
          "[breakpoints][cli]") {
  // The driven pendulum's shaker from a table that ends at 0.55: rows at 0, 0.1, ..., 0.5.
  write("shaker_short.csv", "t,value\n0,0\n0.15,0.01\n0.3,0.02\n0.45,0.01\n0.55,0\n");
  std::ifstream in(example("dynamics/driven_pendulum.yaml"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string from = "f: \"amplitude*sin(omega*t)\"";
  REQUIRE(text.find(from) != std::string::npos);
  text.replace(text.find(from), from.size(), "table: shaker_short.csv");
  const std::string file = write("shaker_short.yaml", text);
  const auto r = kinegen::test::run_command(
      {KINEGEN_EXE, "simulate", file, "--t1", "1", "--steps", "10", "--reference", "16"});
  INFO(r.err);
  CHECK(r.exit_code == 1);
  CHECK(lines(r.out) == 7);  // the header and t = 0 .. 0.5
}

TEST_CASE("the reference never writes a non-finite row (an input table of 1e308)",
          "[breakpoints][cli]") {
  const std::string table =
      write("push_huge.csv", "t,value\n0,1e308\n0.5,1e308\n1,1e308\n2,1e308\n");
  const auto r = kinegen::test::run_command(
      {KINEGEN_EXE, "simulate", example("dynamics/cart_pole.yaml"), "--t1", "1", "--steps", "10",
       "--reference", "16", "--input", "push_x=" + table});
  INFO(r.err);
  CHECK(r.exit_code == 1);
  CHECK(r.err.rfind("error: ", 0) == 0);
  for (const char* bad : {"inf", "nan", "Inf", "NaN"}) CHECK(r.out.find(bad) == std::string::npos);
}
