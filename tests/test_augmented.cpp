// Forward dynamics through singular positions: `kinegen simulate --method augmented`
// (analysis/augmented.hpp: Bayo, Garcia de Jalon and Serna's augmented Lagrangian
// with Bayo and Ledesma's mass-orthogonal projections) against independent truths:
// the N-four-bar of the IFToMM benchmark A02 against the exact one-degree-of-freedom model of
// its parallelogram branch, the energy balance, and the minimal-coordinates method where both
// apply; and the minimal method's safe failure at a singular position (exit 1, the rows so
// far, the time, the constraints named, the advice), never a silent wrong branch.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/augmented.hpp"
#include "kinegen/codegen/analysis/dynamics.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/simulate.hpp"
#include "support/run_command.hpp"

namespace {

namespace fs = std::filesystem;
namespace kc = kinegen::codegen;
using kinegen::test::run_command;

std::string dynamics_example(const std::string& name) {
  return (fs::path(KINEGEN_SOURCE_DIR) / "examples" / "dynamics" / (name + ".yaml")).string();
}

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "augmented";
  fs::create_directories(dir);
  return dir / name;
}

// A CSV of numbers with its header.
struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;
  int column(const std::string& name) const {
    for (std::size_t c = 0; c < header.size(); ++c)
      if (header[c] == name) return static_cast<int>(c);
    FAIL("no column " << name);
    return -1;
  }
};

Table read_table(const fs::path& path) {
  std::ifstream in(path);
  REQUIRE(in);
  Table t;
  std::string line, field;
  REQUIRE(std::getline(in, line));
  std::istringstream h(line);
  while (std::getline(h, field, ',')) t.header.push_back(field);
  while (std::getline(in, line)) {
    std::istringstream r(line);
    std::vector<double> row;
    while (std::getline(r, field, ',')) row.push_back(std::stod(field));
    REQUIRE(row.size() == t.header.size());
    t.rows.push_back(row);
  }
  return t;
}

// The N-four-bar's parallelogram branch as one degree of freedom (examples/dynamics/
// n_four_bar.py): every crank at theta, every coupler horizontal, so the energy is
// 1/2 I theta'^2 + G sin(theta) with I = (N + 1)/3 + N (cranks about their pins, couplers
// translating; unit rods of 1 kg) and G = g (3N + 1) / 2, and theta'' = -G cos(theta) / I.
// Integrated by the classical Runge-Kutta method, `substeps` steps per output interval.
struct ReducedFourBar {
  double inertia, weight;
  explicit ReducedFourBar(int n) : inertia((n + 1) / 3.0 + n), weight(9.81 * (3 * n + 1) / 2) {}
  // theta at each of the times (increasing from 0).
  std::vector<double> theta(const std::vector<double>& times, int substeps) const {
    std::vector<double> out;
    double th = std::acos(-1.0) / 4, w = -std::sqrt(2.0), t = 0;
    const auto acc = [&](double x) { return -weight * std::cos(x) / inertia; };
    for (double target : times) {
      const double h = (target - t) / substeps;
      for (int s = 0; s < substeps && h > 0; ++s) {
        const double k1x = w, k1v = acc(th);
        const double k2x = w + h / 2 * k1v, k2v = acc(th + h / 2 * k1x);
        const double k3x = w + h / 2 * k2v, k3v = acc(th + h / 2 * k2x);
        const double k4x = w + h * k3v, k4v = acc(th + h * k3x);
        th += h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x);
        w += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
      }
      t = target;
      out.push_back(th);
    }
    return out;
  }
  // The first time theta reaches 0 (the first flat position), by bisection on a fine grid.
  double first_flat() const {
    double lo = 0, hi = 1;
    for (int k = 0; k < 60; ++k) {
      const double mid = (lo + hi) / 2;
      (theta({mid}, 20000)[0] > 0 ? lo : hi) = mid;
    }
    return lo;
  }
};

std::vector<double> times_of(const Table& t) {
  std::vector<double> times;
  for (const auto& row : t.rows) times.push_back(row[0]);
  return times;
}

// Runs the in-process simulation (both methods' entry point) into a list of rows.
std::vector<kc::SimulatedRow> simulate(const std::string& file, kc::Method method, double t1,
                                       int steps, double rtol, double atol) {
  kc::BuildOptions build;
  build.free_as_state = true;
  const auto model = kc::CompiledModel::from_file(file, {}, build);
  const kc::ForceModel forces = kc::derive_forces(*model);
  kc::SimulateOptions options;
  options.method = method;
  options.rtol = rtol;
  options.atol = atol;
  std::vector<kc::SimulatedRow> rows;
  kc::run_simulation(
      *model, forces, {0.0, t1, steps}, [&](const kc::SimulatedRow& r) { rows.push_back(r); },
      options);
  return rows;
}

// The N-four-bar's columns against the parallelogram branch's exact motion: B0 on the reduced
// model's circle, every crank at theta, every coupler horizontal. Returns the largest error
// of B0's position.
double check_parallelogram(const Table& t, int n, double branch_tolerance) {
  const ReducedFourBar reduced(n);
  const std::vector<double> theta = reduced.theta(times_of(t), 400);
  const int bx = t.column("B0.x"), by = t.column("B0.y"), th = t.column("theta");
  const int phi0 = t.column("crank_0.phi");
  double worst = 0;
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    const auto& row = t.rows[r];
    worst = std::max(
        {worst, std::abs(row[bx] - std::cos(theta[r])), std::abs(row[by] - std::sin(theta[r]))});
    CHECK(row[th] == row[phi0]);  // the free item's column is crank 0's angle, read off q
    for (int k = 1; k <= n; ++k)
      CHECK(std::abs(row[t.column("crank_" + std::to_string(k) + ".phi")] - row[phi0]) <
            branch_tolerance);
    for (int k = 0; k < n; ++k)
      CHECK(std::abs(row[t.column("coupler_" + std::to_string(k) + ".phi")]) < branch_tolerance);
  }
  return worst;
}

// How many times theta passes a flat position (sin(theta) changes sign) over the rows.
int flat_passes(const Table& t) {
  const int th = t.column("theta");
  int passes = 0;
  for (std::size_t r = 1; r < t.rows.size(); ++r)
    if ((std::sin(t.rows[r - 1][th]) > 0) != (std::sin(t.rows[r][th]) > 0)) ++passes;
  return passes;
}

// `kinegen simulate --method augmented` on the N-four-bar over the benchmark's 20 s.
void n_four_bar_augmented(int n) {
  const fs::path csv = scratch("n_four_bar_" + std::to_string(n) + ".csv");
  const auto r =
      run_command({KINEGEN_EXE, "simulate", dynamics_example("n_four_bar_" + std::to_string(n)),
                   "--t1", "20", "--steps", "400", "--method", "augmented", "--rtol", "1e-13",
                   "--atol", "1e-13", "-q", "-o", csv.string()});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  const Table t = read_table(csv);
  REQUIRE(t.rows.size() == 401);
  // Both flat positions, theta = 0 and -pi, each passed several times (four swings).
  const int th = t.column("theta");
  double lowest = 0;
  for (const auto& row : t.rows) lowest = std::min(lowest, row[th]);
  CHECK(lowest < -std::acos(-1.0));
  CHECK(flat_passes(t) >= 12);
  // The benchmark's tolerance on B0 is 1e-3; the exact reduced model shows far better.
  const double b0 = check_parallelogram(t, n, 1e-6);
  CHECK(b0 < 1e-3);
  CHECK(b0 < 1e-6);
  // The energy balance: nothing does work, so kinetic + potential stays at its start.
  const int balance = t.column("energy.balance");
  double worst = 0;
  for (const auto& row : t.rows) worst = std::max(worst, std::abs(row[balance]));
  CHECK(worst < 1e-6);
  // Z.v and Z.a of the free item against the reduced model: its energy from theta and
  // theta.v, and its closed-form acceleration. Within 0.05 rad of a flat position the modes
  // that become free there are not held as firmly (the cranks' accelerations differ by up to
  // 2e-4 within 1e-4 rad, their rates by 1e-7): looser there.
  const ReducedFourBar reduced(n);
  const int v = t.column("theta.v"), a = t.column("theta.a");
  const double start = reduced.inertia + reduced.weight * std::sin(std::acos(-1.0) / 4);
  for (const auto& row : t.rows) {
    const bool near_flat = std::abs(std::sin(row[th])) < 0.05;
    CHECK(std::abs(row[a] + reduced.weight * std::cos(row[th]) / reduced.inertia) <
          (near_flat ? 1e-3 : 1e-6));
    const double energy =
        0.5 * reduced.inertia * row[v] * row[v] + reduced.weight * std::sin(row[th]);
    CHECK(std::abs(energy - start) < (near_flat ? 1e-5 : 1e-6));
  }
}

}  // namespace

TEST_CASE("the reduced N-four-bar reference is converged", "[augmented]") {
  // Halving the Runge-Kutta step changes theta by less than 1e-11 over the 20 s: the reference
  // is exact to far below what the tests ask of the simulations.
  const ReducedFourBar reduced(4);
  std::vector<double> times;
  for (int k = 1; k <= 40; ++k) times.push_back(0.5 * k);
  const auto coarse = reduced.theta(times, 2000), fine = reduced.theta(times, 4000);
  for (std::size_t k = 0; k < times.size(); ++k) CHECK(std::abs(coarse[k] - fine[k]) < 1e-11);
  // It falls to the first flat position in about 0.29 s, and swings past both.
  const double flat = reduced.first_flat();
  CHECK(flat > 0.28);
  CHECK(flat < 0.29);
}

TEST_CASE("the augmented method passes the N-four-bar's flat positions (N = 4)", "[augmented]") {
  n_four_bar_augmented(4);
}

// The benchmark's own size, nq = 243 (sparse factorization, matrix-free Newton): about 15 s of
// one core, minutes under the sanitizers, so not in the default run: kinegen_tests "[n40]".
// CI's Release pass runs the same checks from Python (python/tests/test_dynamics.py).
TEST_CASE("the augmented method passes the N-four-bar's flat positions (N = 40)", "[.][n40]") {
  n_four_bar_augmented(40);
}

TEST_CASE("the minimal method stops at the N-four-bar's first flat position", "[augmented]") {
  // At every tolerance: exit 1 before or at the first flat position, one error line with the
  // time, the free coordinate's value, the constraints involved and the advice; the rows so
  // far kept, all on the parallelogram branch (never a row past the singular position).
  const double flat = ReducedFourBar(4).first_flat();
  for (const char* rtol : {"1e-3", "1e-6", "1e-8", "1e-12"}) {
    INFO("rtol " << rtol);
    const fs::path csv = scratch(std::string("minimal_") + rtol + ".csv");
    const auto r = run_command({KINEGEN_EXE, "simulate", dynamics_example("n_four_bar_4"), "--t1",
                                "20", "--steps", "400", "--rtol", rtol, "-q", "-o", csv.string()});
    INFO(r.err);
    CHECK(r.exit_code == 1);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(r.err.rfind("error: ", 0) == 0);
    CHECK(r.err.find("singular position") != std::string::npos);
    CHECK(r.err.find("theta = ") != std::string::npos);
    CHECK(r.err.find("involved: ") != std::string::npos);
    CHECK(r.err.find("(revolute)") != std::string::npos);
    CHECK(r.err.find("use --method augmented") != std::string::npos);
    // The time and the free coordinate named are the flat position's: the run stops where
    // Phi_q's condition estimate passes its limit, theta a few 1e-4 rad before the flat, so
    // the time is within the theta bound's 1e-3 rad over theta' (about 4 rad/s there).
    std::smatch m;
    REQUIRE(std::regex_search(r.err, m, std::regex("failed at t = ([0-9.e+-]+)")));
    CHECK(std::abs(std::stod(m[1]) - flat) < 3e-4);
    REQUIRE(std::regex_search(r.err, m, std::regex("theta = ([0-9.e+-]+)")));
    CHECK(std::abs(std::stod(m[1])) < 1e-3);
    // The rows so far: up to the last grid time before the flat position, every one on the
    // parallelogram branch (the cranks parallel to 1e-9, B0 within the tolerance's error).
    const Table t = read_table(csv);
    REQUIRE(t.rows.size() == 6);  // 0, 0.05, ..., 0.25
    CHECK(t.rows.back()[0] < flat);
    CHECK(check_parallelogram(t, 4, 1e-9) < std::max(1e-6, 10 * std::stod(rtol)));
  }
}

TEST_CASE("the minimal method never follows another branch past a singular position",
          "[augmented]") {
  // Walk the free coordinate down to theta = 0.05, then ask for positions past the flat
  // position at theta = 0: each is refused as a singular position or another branch, never
  // returned (on the parallelogram branch past theta = 0, or on the crossed one).
  kc::BuildOptions build;
  build.free_as_state = true;
  const auto model = kc::CompiledModel::from_file(dynamics_example("n_four_bar_4"), {}, build);
  const kc::ForceModel forces = kc::derive_forces(*model);
  for (double past : {-0.001, -0.05, -0.3}) {
    kc::ReducedDynamics dynamics(*model, forces, 0.0);
    kc::MotionState s;
    const double zd = -std::sqrt(2.0);
    for (double z = std::acos(-1.0) / 4; z > 0.05; z -= 0.01)
      REQUIRE(dynamics.evaluate(0.0, &z, &zd, s));
    const double z = 0.05;
    REQUIRE(dynamics.evaluate(0.0, &z, &zd, s));  // the control: this side solves
    CHECK_FALSE(dynamics.evaluate(0.0, &past, &zd, s));
    CHECK((dynamics.failure() == kc::MotionFailure::kBranch ||
           dynamics.failure() == kc::MotionFailure::kPosition));
    CHECK(dynamics.reason().find("singular position") != std::string::npos);
  }
}

TEST_CASE("minimal and augmented methods agree where both apply", "[augmented]") {
  // A pendulum, a four-bar under gravity and a pendulum on a cart that a prescribed driver
  // shakes (its work: the constraints' power), no singular position on their way: the free
  // coordinate, its rate and acceleration, and every coordinate, from both methods. Their
  // difference is integration error: it shrinks with the tolerance (no bias of the
  // augmented Lagrangian's penalty or stabilization), and is within 1e4 rtol of each value's
  // size at rtol 1e-12.
  for (const char* name : {"pendulum", "four_bar_swing", "driven_pendulum"}) {
    INFO(name);
    double loose = 0, tight = 0;
    for (double rtol : {1e-9, 1e-12}) {
      const auto a = simulate(dynamics_example(name), kc::Method::kMinimal, 3, 30, rtol, rtol);
      const auto b = simulate(dynamics_example(name), kc::Method::kAugmented, 3, 30, rtol, rtol);
      REQUIRE(a.size() == 31);
      REQUIRE(b.size() == 31);
      double worst = 0;  // relative to each quantity's size over the run
      const auto compare = [&](auto get) {
        double diff = 0, size = 0;
        for (std::size_t r = 0; r < a.size(); ++r) {
          diff = std::max(diff, std::abs(get(a[r]) - get(b[r])));
          size = std::max(size, std::abs(get(a[r])));
        }
        worst = std::max(worst, diff / (1 + size));
      };
      compare([](const kc::SimulatedRow& r) { return r.z[0]; });
      compare([](const kc::SimulatedRow& r) { return r.zd[0]; });
      compare([](const kc::SimulatedRow& r) { return r.zdd[0]; });
      for (int k = 0; k < a[0].state.q.size(); ++k) {
        compare([k](const kc::SimulatedRow& r) { return r.state.q[k]; });
        compare([k](const kc::SimulatedRow& r) { return r.state.qd[k]; });
        compare([k](const kc::SimulatedRow& r) { return r.state.qdd[k]; });
      }
      compare([](const kc::SimulatedRow& r) { return r.kinetic; });
      compare([](const kc::SimulatedRow& r) { return r.potential; });
      compare([](const kc::SimulatedRow& r) { return r.work; });
      // The augmented method's energy balance (1e-8 of the energy scale).
      double scale = 0, balance = 0;
      for (const auto& r : b) {
        scale = std::max(scale, std::abs(r.kinetic) + std::abs(r.potential));
        balance = std::max(balance, std::abs(r.balance));
      }
      if (rtol < 1e-10) CHECK(balance < 1e-8 * scale);
      (rtol > 1e-10 ? loose : tight) = worst;
    }
    CHECK(tight < loose / 30);
    CHECK(tight < 1e4 * 1e-12);
  }
}

TEST_CASE("the augmented method needs BDF", "[augmented]") {
  const auto r = run_command({KINEGEN_EXE, "simulate", dynamics_example("pendulum"), "--t1", "1",
                              "--steps", "4", "--method", "augmented", "--integrator", "adams"});
  CHECK(r.exit_code == 2);
  CHECK(r.err.find("--integrator bdf") != std::string::npos);
  CHECK(r.out.empty());
}
