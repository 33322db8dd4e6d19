// Numerical stability of the analysis (issue 4): toggle positions, redundant and contradictory
// constraints, assembly branches under coarse steps, units and very long runs. Each case checks
// the exit status, the one `error:` (or `warning:`) line and the rows kept against independent
// truths (closed forms, loop closure, the geometry of the assembly mode).
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <kinegen/solver.hpp>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "support/closed_form.hpp"
#include "support/run_command.hpp"

namespace {

namespace fs = std::filesystem;
namespace kc = kinegen::codegen;
using kinegen::test::CommandResult;

const double kTwoPi = 6.283185307179586;

fs::path stability(const std::string& name) {
  return fs::path(KINEGEN_SOURCE_DIR) / "tests" / "stability" / (name + ".yaml");
}
fs::path example(const std::string& name) {
  return fs::path(KINEGEN_SOURCE_DIR) / "examples" / (name + ".yaml");
}

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "stability" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

CommandResult run_kinegen(std::vector<std::string> args) {
  args.insert(args.begin(), KINEGEN_EXE);
  return kinegen::test::run_command(args);
}

std::string num(double v) {
  std::ostringstream os;
  os.precision(17);
  os << v;
  return os.str();
}

CommandResult analyze(const fs::path& mech, double t0, double t1, int steps,
                      std::vector<std::string> extra = {}) {
  std::vector<std::string> args = {"analyze", mech.string(), "--t0",    num(t0),
                                   "--t1",    num(t1),       "--steps", std::to_string(steps)};
  args.insert(args.end(), extra.begin(), extra.end());
  return run_kinegen(args);
}

// Rows of a CSV as column name -> value.
using Row = std::map<std::string, double>;
std::vector<Row> parse_csv(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  std::vector<std::string> names;
  std::vector<Row> rows;
  if (!std::getline(in, line)) return rows;
  std::istringstream header(line);
  for (std::string cell; std::getline(header, cell, ',');) names.push_back(cell);
  while (std::getline(in, line)) {
    std::istringstream cells(line);
    Row row;
    std::size_t k = 0;
    for (std::string cell; std::getline(cells, cell, ','); ++k) row[names.at(k)] = std::stod(cell);
    REQUIRE(row.size() == names.size());
    rows.push_back(row);
  }
  return rows;
}

void require_one_line(const std::string& err, const std::string& prefix) {
  INFO("stderr: " << err);
  REQUIRE(err.rfind(prefix, 0) == 0);
  REQUIRE(std::count(err.begin(), err.end(), '\n') == 1);
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// The four-bar of examples/four_bar.yaml (a = 1, b = 3.5, c = 2.5, d = 3): the loop closes
// (A + b e^{i phi2} = O4 + c e^{i phi3}) and B lies on the side of line A-O4 of the mode.
void check_four_bar_row(const Row& r, int mode /* +1 open, -1 crossed */) {
  const double p1 = r.at("crank.phi"), p2 = r.at("coupler.phi"), p3 = r.at("rocker.phi");
  const double ax = std::cos(p1), ay = std::sin(p1);
  const double bx = ax + 3.5 * std::cos(p2), by = ay + 3.5 * std::sin(p2);
  INFO("t = " << r.at("t"));
  CHECK(std::abs(bx - (3 + 2.5 * std::cos(p3))) < 1e-9);
  CHECK(std::abs(by - 2.5 * std::sin(p3)) < 1e-9);
  CHECK(std::abs(p1 - r.at("t")) < 1e-12 * std::max(1.0, std::abs(p1)));
  const double side = (3 - ax) * (by - ay) + ay * (bx - ax);  // (O4 - A) x (B - A)
  CHECK(side * mode > 0);
}

}  // namespace

// --- 1. Singular positions and lock-up ---------------------------------------------------------

TEST_CASE("a slider pushed past the reach of its crank stops at the toggle, keeping the rows",
          "[stability]") {
  const fs::path dir = scratch("slider_overdriven");
  const fs::path csv = dir / "out.csv";
  const auto r = analyze(stability("slider_overdriven"), 0, 1, 20, {"-o", csv.string()});
  CHECK(r.exit_code == 1);
  require_one_line(r.err, "error: ");
  CHECK(contains(r.err, stability("slider_overdriven").string()));
  CHECK(contains(r.err, "position analysis failed at t = 0.5"));  // x = 3 at t = 0.5
  CHECK(contains(r.err, "condition estimate"));
  CHECK(contains(r.err, "'crank_pin'"));
  std::ifstream in(csv);
  std::stringstream text;
  text << in.rdbuf();
  const auto rows = parse_csv(text.str());
  REQUIRE(rows.size() == 10);  // t = 0, 0.05, ..., 0.45: everything before the toggle
  for (const auto& row : rows) {
    // Crank tip (cos th, sin th) at distance 2 from the slider at x: cos th = (x^2 - 3) / (2x).
    const double x = 2.5 + row.at("t");
    INFO("t = " << row.at("t"));
    CHECK(std::abs(row.at("rod.x") - x) < 1e-12);
    CHECK(std::abs(std::cos(row.at("crank.phi")) - (x * x - 3) / (2 * x)) < 1e-10);
    CHECK(std::sin(row.at("crank.phi")) > 0);
  }
}

TEST_CASE("a rocker driven past its limit stops there, keeping the rows", "[stability]") {
  // Upper limit acos(-0.6) = 2.2143 rad is reached at t = 0.7095: the sub-steps of the step
  // from 0.70 to 0.75 stop there (tests/test_substeps.cpp: within 1/4096 of the step).
  const auto r = analyze(stability("rocker_overdriven"), 0, 1, 20);
  CHECK(r.exit_code == 1);
  require_one_line(r.err, "error: ");
  CHECK(contains(r.err, "position analysis failed at t = 0.7094"));
  CHECK((contains(r.err, "condition estimate") && contains(r.err, "residual")));
  const auto rows = parse_csv(r.out);
  REQUIRE(rows.size() == 15);  // t = 0 .. 0.70
  for (const auto& row : rows) {
    const double p1 = row.at("crank.phi"), p2 = row.at("coupler.phi"), p3 = row.at("rocker.phi");
    INFO("t = " << row.at("t"));
    CHECK(std::abs(p3 - (1.5048072742452929 + row.at("t"))) < 1e-12);
    CHECK(std::abs(std::cos(p1) + 3.5 * std::cos(p2) - 3 - 2.5 * std::cos(p3)) < 1e-9);
    CHECK(std::abs(std::sin(p1) + 3.5 * std::sin(p2) - 2.5 * std::sin(p3)) < 1e-9);
  }
}

TEST_CASE("velocity and acceleration refuse a singular Phi_q with a condition estimate",
          "[stability]") {
  // The toggle of slider_overdriven at t = 0.5: crank along +x, rod pointing back along -x.
  const auto model = kc::CompiledModel::from_file(stability("slider_overdriven").string());
  kinegen::BasicSolver<kc::ProgramSystem> solver{kc::ProgramSystem(*model)};
  Eigen::VectorXd q(6), qd(6), qdd(6);
  q << 0, 0, 0, 3, 0, std::acos(-1.0);
  const auto v = solver.velocity(q, 0.5, qd);
  CHECK(v.status == kinegen::Status::kSingular);
  CHECK(v.condition > 1e12);
  qd.setZero();
  const auto a = solver.acceleration(q, qd, 0.5, qdd);
  CHECK(a.status == kinegen::Status::kSingular);
  // Slightly before the toggle Phi_q is regular and its condition estimate finite.
  const double x = 2.9, th = std::acos((x * x - 3) / (2 * x));
  q << 0, 0, th, x, 0, std::atan2(std::sin(th), std::cos(th) - x);
  CHECK(solver.velocity(q, 0.4, qd).status == kinegen::Status::kConverged);
  CHECK(std::abs(qd[3] - 1) < 1e-12);  // the driver: x' = 1
}

// --- 2. Redundant and contradictory constraints -------------------------------------------------

TEST_CASE("a double parallelogram runs through its collinear positions with a warning",
          "[stability]") {
  const auto r = analyze(stability("double_parallelogram"), 0, kTwoPi, 72);
  CHECK(r.exit_code == 0);
  require_one_line(r.err, "warning: ");
  CHECK(contains(r.err, "redundant"));
  CHECK(contains(r.err, "rank 12"));
  CHECK(contains(r.err, "joints[4] 'A2'"));
  const auto rows = parse_csv(r.out);
  REQUIRE(rows.size() == 73);
  int collinear = 0;
  for (const auto& row : rows) {
    const double t = row.at("t");
    INFO("t = " << t);
    if (std::abs(std::sin(t)) < 1e-12) ++collinear;
    for (const char* c : {"crank1", "crank2", "crank3"}) {
      CHECK(std::abs(row.at(std::string(c) + ".phi") - t) < 1e-10);
      CHECK(std::abs(row.at(std::string(c) + ".omega") - 1) < 1e-9);
      CHECK(std::abs(row.at(std::string(c) + ".alpha")) < 1e-8);
    }
    CHECK(std::abs(row.at("coupler.x") - std::cos(t)) < 1e-10);
    CHECK(std::abs(row.at("coupler.y") - std::sin(t)) < 1e-10);
    CHECK(std::abs(row.at("coupler.phi")) < 1e-10);
    CHECK(std::abs(row.at("coupler.vx") + std::sin(t)) < 1e-9);
    CHECK(std::abs(row.at("coupler.ay") + std::sin(t)) < 1e-8);
  }
  CHECK(collinear == 3);  // t = 0, pi, 2 pi
}

TEST_CASE("--strict makes redundancy an error (exit 2) and writes nothing", "[stability]") {
  const fs::path dir = scratch("strict");
  const fs::path csv = dir / "out.csv";
  const auto r =
      analyze(stability("double_parallelogram"), 0, kTwoPi, 72, {"--strict", "-o", csv.string()});
  CHECK(r.exit_code == 2);
  require_one_line(r.err, "error: ");
  CHECK(contains(r.err, stability("double_parallelogram").string()));
  CHECK(contains(r.err, "redundant"));
  CHECK(contains(r.err, "--strict"));
  CHECK(fs::is_empty(dir));
}

TEST_CASE("contradictory drivers fail to assemble with a residual report", "[stability]") {
  const fs::path dir = scratch("contradictory");
  const fs::path csv = dir / "out.csv";
  const auto r = analyze(stability("contradictory_drivers"), 0, 1, 4, {"-o", csv.string()});
  CHECK(r.exit_code == 1);
  require_one_line(r.err, "error: ");
  CHECK(contains(r.err, "at t = 0:"));
  CHECK(contains(r.err, "not satisfied"));
  // The least-squares compromise splits the 0.1 rad disagreement between the two drivers.
  CHECK(contains(r.err, "largest residual 0.05"));
  CHECK(contains(r.err, "'motor'"));
  CHECK(contains(r.err, "'encoder'"));
  CHECK(fs::is_empty(dir));  // nothing was solved, so nothing is kept
}

// --- 3. Assembly branches
// -------------------------------------------------------------------------

TEST_CASE("a four-bar driven with coarse steps stays on its branch or says it cannot",
          "[stability]") {
  for (const auto& [name, mode] :
       {std::pair<std::string, int>{"four_bar", 1}, {"four_bar_crossed", -1}}) {
    const fs::path mech = name == "four_bar" ? example(name) : stability(name);
    for (int steps : {1, 2, 3, 4, 5, 6, 8, 12}) {
      INFO(name << " with " << steps << " steps per turn");
      const auto r = analyze(mech, 0, kTwoPi, steps);
      const auto rows = parse_csv(r.out);
      for (const auto& row : rows) check_four_bar_row(row, mode);  // never a wrong result
      if (r.exit_code == 0) {
        CHECK(r.err.empty());
        CHECK(rows.size() == static_cast<std::size_t>(steps + 1));
      } else {
        CHECK(r.exit_code == 1);
        require_one_line(r.err, "error: ");
        CHECK(contains(r.err, "--steps"));
      }
      // Followed at every grid, down to one step per turn: a refused step is taken in
      // sub-steps (without them, 2 steps per turn were refused).
      CHECK(r.exit_code == 0);
    }
  }
}

TEST_CASE("a jump to another branch is detected, not returned", "[stability]") {
  // The quick-return's rocker angle is atan2(d + r sin phi1, r cos phi1). With three steps per
  // turn, Newton from the predicted point converges at t = 2 pi to the right place but the
  // wrong turn (or the wrong branch); the check against the velocities catches it.
  const auto model = kc::CompiledModel::from_file(example("quick_return").string());
  std::vector<kc::StateRow> rows;
  const auto sink = [&](const kc::StateRow& row) { rows.push_back(row); };
  // The dense Newton on all of Phi_q (the block solver, below, stays on the branch here).
  kc::AnalysisOptions dense;
  dense.block_solver = false;
  kc::AnalysisOptions lax = dense;
  lax.check_jumps = false;  // detection off: what would have been returned
  kc::run_analysis(*model, {0, kTwoPi, 3}, sink, lax);
  REQUIRE(rows.size() == 4);
  const auto exact = kinegen::closed_form::quick_return_state(kTwoPi);
  double worst = 0;
  for (int k = 0; k < 9; ++k) worst = std::max(worst, std::abs(rows.back().q[k] - exact.q[k]));
  CHECK(worst > 0.1);  // a wrong answer without the check
  rows.clear();
  kc::AnalysisOptions plain = dense;
  plain.substep_halvings = 0;  // one Newton start per row: the jump is refused, an error
  try {
    kc::run_analysis(*model, {0, kTwoPi, 3}, sink, plain);
    FAIL("no error");
  } catch (const kc::AnalysisError& e) {
    CHECK((contains(e.what(), "jumped") || contains(e.what(), "det(Phi_q) changed sign")));
    CHECK(contains(e.what(), "--steps"));
    CHECK(contains(e.what(), "t = 6.28"));
  }
  CHECK(rows.size() == 3);  // the rows before are kept
  // With sub-steps (analyze's default) the refused step is taken in halves: the right rows.
  rows.clear();
  kc::run_analysis(*model, {0, kTwoPi, 3}, sink, dense);
  REQUIRE(rows.size() == 4);
  for (int k = 0; k < 9; ++k) CHECK(std::abs(rows.back().q[k] - exact.q[k]) < 1e-12);
  // The block solver (the default, as generated code): Newton on the rocker's block alone
  // from the predicted point converges on the right branch; a failure would be an error too,
  // never a wrong row.
  rows.clear();
  kc::run_analysis(*model, {0, kTwoPi, 3}, sink, kc::AnalysisOptions{});
  REQUIRE(rows.size() == 4);
  for (int k = 0; k < 9; ++k) CHECK(std::abs(rows.back().q[k] - exact.q[k]) < 1e-12);
}

// --- 4. Units and long runs -------------------------------------------------------------------

TEST_CASE("the four-bar in metres and in millimetres gives the same angles to 1e-12",
          "[stability]") {
  const auto m = parse_csv(analyze(example("four_bar"), 0, kTwoPi, 360).out);
  const auto mm = parse_csv(analyze(stability("four_bar_mm"), 0, kTwoPi, 360).out);
  REQUIRE(m.size() == 361);
  REQUIRE(mm.size() == 361);
  double worst_angle = 0, worst_length = 0;
  for (std::size_t k = 0; k < m.size(); ++k)
    for (const auto& [name, v] : m[k]) {
      if (name == "t") continue;
      const bool angle =
          contains(name, ".phi") || contains(name, ".omega") || contains(name, ".alpha");
      // Relative to the quantity, or to 1 (rad, m) where it passes near zero.
      const double err =
          std::abs(mm[k].at(name) / (angle ? 1.0 : 1000.0) - v) / std::max(std::abs(v), 1.0);
      (angle ? worst_angle : worst_length) = std::max(angle ? worst_angle : worst_length, err);
    }
  INFO("worst angle " << worst_angle << ", worst length " << worst_length);
  CHECK(worst_angle < 1e-12);
  CHECK(worst_length < 1e-12);
}

TEST_CASE("after 1e6 crank turns the four-bar is as accurate as its inputs allow", "[stability]") {
  const double t0 = 1e6 * kTwoPi;
  // The first solve follows the drivers from the q0 pose (docs/embedding.md, "First solves and
  // branches"): 1e6 turns from it is too far, refused with the reason; a q0 near t0 is the way.
  const auto far = analyze(example("four_bar"), t0, t0 + kTwoPi, 36);
  CHECK(far.exit_code == 1);
  CHECK(contains(far.err, "too far"));
  std::ifstream in(example("four_bar"));
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml = text.str();
  const std::string crank_q0 = "q0: [0.0, 0.0, 0.0]";
  REQUIRE(yaml.find(crank_q0) != std::string::npos);
  std::ostringstream near;
  near.precision(17);
  near << "q0: [0.0, 0.0, " << t0 << "]";
  yaml.replace(yaml.find(crank_q0), crank_q0.size(), near.str());
  const fs::path file = scratch("far_turns") / "four_bar.yaml";
  std::ofstream(file) << yaml;
  const auto r = analyze(file, t0, t0 + kTwoPi, 36);
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  const auto rows = parse_csv(r.out);
  REQUIRE(rows.size() == 37);
  const double eps = std::numeric_limits<double>::epsilon();
  for (const auto& row : rows) {
    const double p1 = row.at("crank.phi");
    INFO("t = " << row.at("t"));
    // The driver's angle is omega t in double: exact up to the rounding of t itself.
    CHECK(std::abs(p1 - row.at("t")) <= 4 * eps * std::abs(p1));
    // Against the closed form at that very crank angle, the error is bounded by the rounding
    // of an angle of |p1| (eps |p1| ~ 1.4e-9), amplified by the linkage's gains (< 10 here).
    const auto exact = kinegen::closed_form::four_bar_state(p1);
    const double bound = 64 * eps * std::abs(p1);
    // The angles stay in the turn of their estimates in the file (not 1e6 turns away).
    CHECK(row.at("coupler.phi") == Approx(exact.q[5]).margin(bound));
    CHECK(row.at("rocker.phi") == Approx(exact.q[8]).margin(bound));
    CHECK(row.at("rocker.omega") == Approx(exact.qd[8]).margin(bound));
    CHECK(row.at("rocker.alpha") == Approx(exact.qdd[8]).margin(bound));
    CHECK(row.at("coupler.x") == Approx(exact.q[3]).margin(bound));
  }
}

TEST_CASE("Newton's residual is rechecked after its step criterion", "[stability]") {
  // A consistent system converges with a residual far inside the bound; a contradictory one,
  // whose least-squares step vanishes at a non-zero residual, is not accepted.
  const auto ok = kc::CompiledModel::from_file(example("four_bar").string());
  kinegen::BasicSolver<kc::ProgramSystem> solver{kc::ProgramSystem(*ok)};
  Eigen::VectorXd q = ok->q0();
  const auto r = solver.position(q, 0.3);
  REQUIRE(r);
  CHECK(r.residual <= 1e-8);
  const auto bad = kc::CompiledModel::from_file(stability("contradictory_drivers").string());
  kinegen::BasicSolver<kc::ProgramSystem> lsq{kc::ProgramSystem(*bad)};
  q = bad->q0();
  const auto r2 = lsq.position(q, 0.0);
  CHECK(r2.status == kinegen::Status::kInconsistent);
  CHECK(r2.residual > 1e-3);
}
