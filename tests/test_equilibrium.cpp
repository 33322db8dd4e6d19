// `kinegen equilibrium` answers where a mechanism comes to rest (docs/stability.md): a slider
// held by an inclined spring that has two stable rests returns the one its overdamped release
// reaches, checked against a closed form of its potential and against `kinegen simulate` with a
// damper above critical in every mode; --nearest and --from; `modes --at` at the printed point
// is an equilibrium; modes of a very large and of a negative damping labelled from the damped
// system's eigenvalues, against the roots of m s^2 + c s + k.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "kinegen/codegen/analysis/equilibrium.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "support/run_command.hpp"

namespace fs = std::filesystem;
namespace kc = kinegen::codegen;
using kinegen::test::CommandResult;

namespace {

constexpr double kPi = 3.14159265358979323846;

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "equilibrium" / name;
  fs::create_directories(dir);
  return dir;
}

fs::path write(const fs::path& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

CommandResult run_kinegen(const std::vector<std::string>& args) {
  std::vector<std::string> argv{KINEGEN_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  return kinegen::test::run_command(argv, {});
}

// The value after "NAME = " on its own line of the text output.
double value_of(const std::string& text, const std::string& name) {
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(name + " = ", 0) == 0) return std::stod(line.substr(name.size() + 3));
  FAIL("no line '" << name << " = ' in:\n" << text);
  return 0;
}

// A block on a horizontal rail, pulled by a spring from the ground point (0, h) and pushed by
// a constant force F along the rail: V(x) = k/2 (sqrt(x^2 + h^2) - L0)^2 - F x, with L0 > h a
// snap-through with two stable rests either side of a maximum. `damper` adds -c xd_block.
constexpr double kM = 2.0, kK = 1000, kH = 0.3, kL0 = 0.5, kF = 20;

std::string snap_through(double value0, double damper) {
  std::ostringstream s;
  s.precision(17);
  s << "name: snap_through\n"
    << "parameters: {m: " << kM << ", k: " << kK << ", h: " << kH << ", L0: " << kL0
    << ", F: " << kF << ", c: " << damper << "}\n"
    << "bodies:\n"
    << "  - {name: block, q0: [" << value0 << ", 0, 0], mass: m, inertia: 0.01}\n"
    << "joints:\n"
    << "  - {type: translational, i: ground, j: block, vi: [1, 0]}\n"
    << "free:\n"
    << "  - {type: absolute_x, name: x, body: block, value0: " << value0 << "}\n"
    << "forces:\n"
    << "  - {type: spring_damper, i: ground, j: block, si: [0, h], stiffness: k, length0: L0}\n"
    << "  - {type: force, body: block, f: [\"F - c*xd_block\", 0]}\n";
  return s.str();
}

double v_prime(double x) {
  const double r = std::hypot(x, kH);
  return kK * (r - kL0) * x / r - kF;
}

double v_second(double x) {
  const double r = std::hypot(x, kH);
  return kK * (1 - kL0 * kH * kH / (r * r * r));
}

// The zero of V' between a and b (a sign change) by bisection to the last bit.
double zero_between(double a, double b) {
  REQUIRE(v_prime(a) * v_prime(b) < 0);
  for (;;) {
    const double mid = (a + b) / 2;
    if (mid == a || mid == b) return std::abs(v_prime(a)) < std::abs(v_prime(b)) ? a : b;
    (v_prime(a) * v_prime(mid) <= 0 ? b : a) = mid;
  }
}

// The last row's value of column `name` of a CSV.
double last_row(const fs::path& csv, const std::string& name) {
  std::ifstream in(csv);
  std::string header, line, last;
  std::getline(in, header);
  while (std::getline(in, line))
    if (!line.empty()) last = line;
  std::vector<std::string> names, cells;
  for (std::stringstream h(header); std::getline(h, line, ',');) names.push_back(line);
  for (std::stringstream r(last); std::getline(r, line, ',');) cells.push_back(line);
  const auto it = std::find(names.begin(), names.end(), name);
  REQUIRE(it != names.end());
  return std::stod(cells[static_cast<std::size_t>(it - names.begin())]);
}

}  // namespace

TEST_CASE("equilibrium: of two stable rests, the one the overdamped release reaches",
          "[equilibrium]") {
  // V' < 0 at x0 = -0.02: the block is pushed right, over no barrier, to the right-hand rest,
  // though the left-hand rest is nearer; Newton from x0 finds the maximum between them.
  const double x0 = -0.02;
  REQUIRE(v_prime(x0) < 0);
  const double left = zero_between(-0.6, -0.2), top = zero_between(-0.2, 0.0),
               right = zero_between(0.2, 0.6);
  REQUIRE(v_second(left) > 0);
  REQUIRE(v_second(top) < 0);
  REQUIRE(v_second(right) > 0);
  REQUIRE(std::abs(left - x0) < std::abs(right - x0));
  const fs::path dir = scratch("two_rests");
  const fs::path yaml = write(dir / "snap.yaml", snap_through(x0, 0));
  const CommandResult rest = run_kinegen({"equilibrium", yaml.string()});
  INFO(rest.err);
  REQUIRE(rest.exit_code == 0);
  CHECK(rest.out.find(": stable") != std::string::npos);
  CHECK(value_of(rest.out, "x") == Approx(right).margin(1e-13));
  const CommandResult nearest = run_kinegen({"equilibrium", yaml.string(), "--nearest"});
  REQUIRE(nearest.exit_code == 0);
  CHECK(nearest.out.find(": unstable") != std::string::npos);
  CHECK(value_of(nearest.out, "x") == Approx(top).margin(1e-13));
  // --from sets the start: from -0.1 (V' > 0) it comes to rest on the left.
  REQUIRE(v_prime(-0.1) > 0);
  const CommandResult from = run_kinegen({"equilibrium", yaml.string(), "--from", "x=-0.1"});
  REQUIRE(from.exit_code == 0);
  CHECK(value_of(from.out, "x") == Approx(left).margin(1e-13));
  // The release itself: a damper far above critical in every position (c^2 > 4 m max|V''|,
  // |V''| <= k), run until it has settled.
  const double c = 4 * std::sqrt(kM * kK);
  const fs::path damped = write(dir / "damped.yaml", snap_through(x0, c)), csv = dir / "run.csv";
  const CommandResult run = run_kinegen(
      {"simulate", damped.string(), "--t1", "40", "--steps", "40", "-q", "-o", csv.string()});
  INFO(run.err);
  REQUIRE(run.exit_code == 0);
  CHECK(last_row(csv, "x") == Approx(right).margin(1e-6));
  // The damper changes no rest: the same answer with it.
  const CommandResult rest_damped = run_kinegen({"equilibrium", damped.string()});
  REQUIRE(rest_damped.exit_code == 0);
  CHECK(value_of(rest_damped.out, "x") == Approx(right).margin(1e-13));
}

TEST_CASE("modes --at the point equilibrium printed is an equilibrium there", "[equilibrium]") {
  // A pendulum: at rest its generalized force m g a cos(theta) is 6e-17 m g a at best (no
  // double is closer to -pi/2), far below any step Newton could take.
  const fs::path dir = scratch("modes_at");
  const fs::path yaml = write(dir / "pendulum.yaml", R"(
name: pendulum
parameters: {m: 1.5, a: 0.4, g: 9.81}
bodies:
  - {name: rod, q0: [0, 0, 0], mass: m, inertia: "m*(2*a)^2/12", com: [a, 0]}
joints:
  - {type: revolute, i: ground, j: rod}
free:
  - {type: absolute_angle, name: theta, body: rod, value0: -1.2}
gravity: [0, -g]
)");
  for (const char* file : {"pendulum", "four_bar_spring"}) {
    INFO(file);
    const std::string path =
        std::string(file) == "pendulum"
            ? yaml.string()
            : std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/four_bar_spring.yaml";
    const CommandResult e = run_kinegen({"equilibrium", path});
    REQUIRE(e.exit_code == 0);
    std::ostringstream at;
    at.precision(17);
    at << "theta=" << value_of(e.out, "theta");
    const CommandResult m = run_kinegen({"modes", path, "--at", at.str()});
    INFO(m.err);
    REQUIRE(m.exit_code == 0);
    CHECK(m.err.find("not an equilibrium") == std::string::npos);
    // A point 1e-6 rad away is not one.
    const CommandResult off = run_kinegen(
        {"modes", path, "--at", "theta=" + std::to_string(value_of(e.out, "theta") + 1e-6)});
    REQUIRE(off.exit_code == 0);
    CHECK(off.err.find("not an equilibrium") != std::string::npos);
  }
  CHECK(value_of(run_kinegen({"equilibrium", yaml.string()}).out, "theta") ==
        Approx(-kPi / 2).margin(1e-15));
}

namespace {

// A block on a rail with a spring k and a damper c to the ground (the rest at x = 0).
std::string oscillator(double k, double c) {
  std::ostringstream s;
  s.precision(17);
  s << "name: oscillator\n"
    << "bodies:\n"
    << "  - {name: block, q0: [0, 0, 0], mass: 1, inertia: 0.01}\n"
    << "joints:\n"
    << "  - {type: translational, i: ground, j: block, vi: [1, 0]}\n"
    << "free:\n"
    << "  - {type: absolute_x, name: x, body: block, value0: 0.1}\n"
    << "forces:\n"
    << "  - {type: spring_damper, i: ground, j: block, si: [-1, 0], stiffness: " << k
    << ", damping: " << c << ", length0: 1}\n";
  return s.str();
}

struct Modes {
  std::unique_ptr<kc::CompiledModel> model;
  kc::ForceModel forces;
  std::unique_ptr<kc::Linearizer> lin;
  kc::ModalAnalysis modes;
  explicit Modes(const std::string& yaml)
      : model(compile(yaml)), forces(kc::derive_forces(*model)) {
    lin = std::make_unique<kc::Linearizer>(*model, forces, 0.0);
    modes = kc::modal_analysis(*lin, kc::find_equilibrium(*lin, lin->initial()).at);
  }
  static std::unique_ptr<kc::CompiledModel> compile(const std::string& yaml) {
    kc::BuildOptions build;
    build.free_as_state = true;
    return kc::CompiledModel::from_mechanism(kc::parse_mechanism(yaml, "test.yaml"), {}, build);
  }
};

}  // namespace

TEST_CASE("modes: a stiffness under a very large damper is no zero stiffness", "[equilibrium]") {
  // m s^2 + c s + k = 0 with m = 1, k = 15.2, c = 1e6: two real roots, both decaying, the slow
  // one s = -2k / (c + sqrt(c^2 - 4 m k)), about -k/c = -1.52e-5 (1e-11 of the fast one).
  const double k = 15.2, c = 1e6;
  const Modes m(oscillator(k, c));
  REQUIRE(m.modes.damped);
  REQUIRE(m.modes.modes.size() == 2);
  CHECK(m.modes.stability == kc::Stability::kStable);
  const double slow = -2 * k / (c + std::sqrt(c * c - 4 * k)), fast = k / slow;
  std::vector<double> roots;
  for (const kc::Mode& mode : m.modes.modes) {
    CHECK(mode.kind == kc::Stability::kStable);
    roots.push_back(mode.eigenvalue);
  }
  std::sort(roots.begin(), roots.end());
  CHECK(roots[0] == Approx(fast).epsilon(1e-9));
  CHECK(roots[1] == Approx(slow).epsilon(1e-6));
  const fs::path yaml = write(scratch("labels") / "heavy.yaml", oscillator(k, c));
  const CommandResult r = run_kinegen({"modes", yaml.string()});
  REQUIRE(r.exit_code == 0);
  CHECK(r.out.find("neutral") == std::string::npos);
  CHECK(r.out.find("(the equilibrium): stable") != std::string::npos);
}

TEST_CASE("modes: a negative damping makes a growing oscillation, with its frequency",
          "[equilibrium]") {
  // m = 1, k = (2 pi 1.05)^2, c = -0.5: s = -c/2 +- i sqrt(k - c^2/4), f = sqrt(k)/(2 pi) =
  // 1.05 Hz, zeta = c / (2 sqrt(k)) < 0. K_z alone is positive: the point is statically
  // stable, and the modes say it grows.
  const double f = 1.05, k = std::pow(2 * kPi * f, 2), c = -0.5;
  const Modes m(oscillator(k, c));
  REQUIRE(m.modes.modes.size() == 1);
  CHECK(m.modes.stiffness.stability == kc::Stability::kStable);
  CHECK(m.modes.stability == kc::Stability::kUnstable);
  const kc::Mode& mode = m.modes.modes[0];
  CHECK(mode.kind == kc::Stability::kUnstable);
  CHECK(mode.frequency == Approx(f).epsilon(1e-12));
  CHECK(mode.damping_ratio == Approx(c / (2 * std::sqrt(k))).epsilon(1e-12));
  CHECK(mode.damped_frequency == Approx(std::sqrt(k - c * c / 4) / (2 * kPi)).epsilon(1e-12));
  const fs::path yaml = write(scratch("labels") / "negative.yaml", oscillator(k, c));
  const CommandResult r = run_kinegen({"modes", yaml.string()});
  REQUIRE(r.exit_code == 0);
  INFO(r.out);
  CHECK(r.out.find("(the equilibrium): unstable") != std::string::npos);
  const std::string label = "mode 1: unstable (it grows), ";
  const std::size_t at = r.out.find(label);
  REQUIRE(at != std::string::npos);
  CHECK(std::stod(r.out.substr(at + label.size())) == Approx(f).epsilon(1e-12));
  CHECK(r.out.find(" Hz, damping ratio -0.0378", at) != std::string::npos);
}
