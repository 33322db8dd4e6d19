// `kinegen equilibrium`, `modes`, `linearize` and `animate --mode` end to end: a neutral
// direction (a free wheel) reported as such, no equilibrium (a torque no position balances) an
// exit 1 with its message, bad input one error line each (modes without free coordinates, --at
// with an unknown name or a wrong count), linearize without inputs an empty B, the modes' JSON
// read back by `kinegen view`'s reader, a mode drawn by animate.
#include <algorithm>
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/io/view.hpp"
#include "support/run_command.hpp"

namespace fs = std::filesystem;
using kinegen::test::CommandResult;

namespace {

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "cli_linear" / name;
  fs::create_directories(dir);
  return dir;
}

fs::path write(const fs::path& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

std::string read(const fs::path& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

CommandResult run_kinegen(const std::vector<std::string>& args) {
  std::vector<std::string> argv{KINEGEN_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  return kinegen::test::run_command(argv, {});
}

void require_one_error_line(const CommandResult& r, int code, const std::string& what) {
  INFO("stderr: " << r.err);
  CHECK(r.exit_code == code);
  REQUIRE(r.err.rfind("error: ", 0) == 0);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK(r.err.find(what) != std::string::npos);
  CHECK(r.out.empty());
}

std::string example(const std::string& name) {
  return std::string(KINEGEN_SOURCE_DIR) + "/examples/" + name;
}

// A pendulum with a wheel free to spin at its tip: the spin has no stiffness.
const char* const kPendulumWheel = R"(
name: pendulum_wheel
parameters: {m: 1.5, a: 0.4, g: 9.81}
bodies:
  - {name: rod, q0: [0, 0, -1.5], mass: m, inertia: "m*(2*a)^2/12", com: [a, 0]}
  - {name: wheel, q0: [0.06, -0.8, 0], mass: 0.5, inertia: 0.01}
joints:
  - {type: revolute, i: ground, j: rod}
  - {type: revolute, i: rod, j: wheel, si: ["2*a", 0]}
free:
  - {type: absolute_angle, name: theta, body: rod, value0: -1.2}
  - {type: absolute_angle, name: spin, body: wheel, value0: 0}
gravity: [0, -g]
)";

// A pendulum driven by a torque larger than its weight's largest moment: it turns for ever.
const char* const kOverdriven = R"(
name: overdriven
parameters: {m: 1.5, a: 0.4, g: 9.81}
bodies:
  - {name: rod, q0: [0, 0, 0], mass: m, inertia: "m*(2*a)^2/12", com: [a, 0]}
joints:
  - {type: revolute, i: ground, j: rod}
free:
  - {type: absolute_angle, name: theta, body: rod, value0: -1.2}
gravity: [0, -g]
forces:
  - {type: torque, body: rod, value: 10}
)";

}  // namespace

TEST_CASE("equilibrium: a free wheel's spin is a neutral direction", "[cli_linear]") {
  const fs::path yaml = write(scratch("neutral") / "wheel.yaml", kPendulumWheel);
  const CommandResult r = run_kinegen({"equilibrium", yaml.string()});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  CHECK(r.out.find("neutral: zero stiffness (K_z singular) along spin") != std::string::npos);
  CHECK(r.out.find("theta = -1.5707963267948966") != std::string::npos);
  const CommandResult m = run_kinegen({"modes", yaml.string()});
  REQUIRE(m.exit_code == 0);
  CHECK(m.out.find("mode 1: neutral (zero stiffness)") != std::string::npos);
}

TEST_CASE("equilibrium: loads that balance nowhere are exit 1, never an answer", "[cli_linear]") {
  const fs::path dir = scratch("none");
  const fs::path yaml = write(dir / "overdriven.yaml", kOverdriven), out = dir / "eq.json";
  const CommandResult r = run_kinegen({"equilibrium", yaml.string(), "-o", out.string()});
  require_one_error_line(r, 1, "no equilibrium near value0 (theta = -1.2)");
  CHECK_FALSE(fs::exists(out));
  // The same with the modes about it.
  require_one_error_line(run_kinegen({"modes", yaml.string()}), 1, "no equilibrium near value0");
}

TEST_CASE("equilibrium, modes, linearize: bad input is one error line", "[cli_linear]") {
  const std::string pendulum = example("dynamics/pendulum.yaml");
  require_one_error_line(run_kinegen({"modes", example("slider_crank.yaml")}), 2,
                         "`kinegen modes` needs free coordinates");
  require_one_error_line(run_kinegen({"equilibrium", example("four_bar.yaml")}), 2,
                         "needs free coordinates");
  require_one_error_line(run_kinegen({"modes", pendulum, "--at", "psi=0.3"}), 2,
                         "--at: unknown name 'psi' (known: t, z, u, theta)");
  require_one_error_line(run_kinegen({"linearize", pendulum, "--at", "z=0.1,0.2"}), 2,
                         "--at z expects 1 value, one per free coordinate (theta), got 2");
  require_one_error_line(
      run_kinegen({"linearize", example("dynamics/cart_pole.yaml"), "--at", "u=1,2"}), 2,
      "--at u expects 1 value, one per run-time input (push_x), got 2");
  require_one_error_line(run_kinegen({"linearize", pendulum, "--at", "zd=x"}), 2,
                         "'x' is not a finite number");
  require_one_error_line(run_kinegen({"equilibrium", pendulum, "--at", "z=1"}), 2,
                         "--at: unknown name 'z' (known: t, u)");
}

TEST_CASE("linearize: no run-time inputs give an empty B, no error", "[cli_linear]") {
  const CommandResult r = run_kinegen({"linearize", example("dynamics/pendulum.yaml")});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  CHECK(r.err.empty());
  CHECK(r.out.find("\"inputs\": []") != std::string::npos);
  CHECK(r.out.find("\"B\": [[], []]") != std::string::npos);
  // By name, and as CSV: [A | B] with the states' names.
  const CommandResult c = run_kinegen({"linearize", example("dynamics/cart_pole.yaml"), "--at",
                                       "phi=1.5,x.v=0.2,push_x=1", "--format", "csv"});
  REQUIRE(c.exit_code == 0);
  std::istringstream lines(c.out);
  std::string header;
  std::getline(lines, header);
  CHECK(header == "state,x,phi,x.v,phi.v,push_x");
  int rows = 0;
  for (std::string line; std::getline(lines, line);) ++rows;
  CHECK(rows == 4);
}

TEST_CASE("modes: its JSON is what kinegen view plays; animate --mode draws one", "[cli_linear]") {
  const fs::path dir = scratch("modes");
  const std::string path = example("dynamics/four_bar_damped.yaml");
  const fs::path json = dir / "modes.json", svg = dir / "mode.svg";
  const CommandResult r = run_kinegen({"modes", path, "-o", json.string()});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  kinegen::codegen::BuildOptions build;
  build.free_as_state = true;
  const auto model = kinegen::codegen::CompiledModel::from_file(path, {}, build);
  const kinegen::codegen::ModeSet modes = kinegen::codegen::read_modes_json(json.string(), *model);
  REQUIRE(modes.frequencies.size() == 1);
  CHECK(modes.frequencies[0] > 2.1);
  CHECK(modes.frequencies[0] < 2.2);
  CHECK(read(json).find("\"damping_ratios\": [0.05") != std::string::npos);
  const CommandResult a = run_kinegen({"animate", path, "--mode", "1", "-o", svg.string()});
  INFO(a.err);
  REQUIRE(a.exit_code == 0);
  const std::string text = read(svg);
  CHECK(text.find("four_bar_damped   mode 1: 2.167 Hz") != std::string::npos);
  CHECK(text.find("<animate") != std::string::npos);
  require_one_error_line(run_kinegen({"animate", path, "--mode", "2", "-o", svg.string()}), 2,
                         "--mode 2: the mechanism has 1 mode (1..1)");
}

TEST_CASE("a load's input reads --input as a table: the cart-pole pushed, energy balanced",
          "[cli_linear]") {
  const fs::path dir = scratch("load_input");
  const fs::path table = write(dir / "push.csv", "t,value\n0,2\n0.5,2\n1,2\n1.5,2\n2,2\n");
  const fs::path out = dir / "run.csv";
  const std::string path = example("dynamics/cart_pole.yaml");
  // Without its table, simulate cannot run it (a usage error naming the input).
  require_one_error_line(run_kinegen({"simulate", path, "--t1", "0.3", "--steps", "3"}), 2,
                         "give its values with --input push_x=FILE.csv");
  const CommandResult r =
      run_kinegen({"simulate", path, "--t1", "0.3", "--steps", "3", "--rtol", "1e-10", "--input",
                   "push_x=" + table.string(), "-q", "-o", out.string()});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  std::istringstream csv(read(out));
  std::string header, line, last;
  std::getline(csv, header);
  while (std::getline(csv, line)) last = line;
  std::vector<std::string> names, values;
  for (std::istringstream h(header); std::getline(h, line, ',');) names.push_back(line);
  for (std::istringstream v(last); std::getline(v, line, ',');) values.push_back(line);
  const auto column = [&](const std::string& name) {
    const auto at = std::find(names.begin(), names.end(), name);
    REQUIRE(at != names.end());
    return std::stod(values[at - names.begin()]);
  };
  // The push did work (it moved the cart along +x), and the energy balance holds.
  CHECK(column("energy.work") > 0.01);
  CHECK(std::abs(column("energy.balance")) < 1e-8 * column("energy.work"));
  CHECK(column("x") > 0);
}
