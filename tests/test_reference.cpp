// The high-precision reference (codegen/reference.hpp) and the stated error bound of the double
// analysis against it (docs/accuracy.md):
//  1. the 40-digit reference itself agrees with hand-derived closed forms, written here as
//     GiNaC expressions of t and differentiated by GiNaC, evaluated at 50 digits, to 1e-30;
//  2. over a full crank turn (360 steps), for every example, the double analysis (in-process
//     run_analysis, and Solver<Model> on the committed generated header) is within
//         err_block <= c_block * kappa * eps
//     of the reference at every step, where kappa is the condition number of the scaled
//     Jacobian at that step and err_block is measured in units of the block's own size.
#include <Eigen/Dense>
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <kinegen/solver.hpp>
#include <limits>
#include <string>
#include <vector>

#include "four_bar.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "offset_slider_crank.hpp"
#include "quick_return.hpp"
#include "slider_crank.hpp"
#include "slider_crank_lecture.hpp"
#include "support/run_command.hpp"

namespace {

namespace cg = kinegen::codegen;
namespace fs = std::filesystem;
using GiNaC::ex;
using GiNaC::numeric;

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr int kSteps = 360;
constexpr int kDigits = 40;
// Every example turns its crank at omega = 1 rad/s (asserted below): a full turn is 2 pi s.
const double kTurn = 2 * std::acos(-1.0);

// The stated bound: err <= c * kappa * eps per block, errors in ulps of the block's size.
// Positions: Newton stops at a scaled step <= 1e-10 and converges quadratically, so the last
// correction leaves an error of order 1e-20, below rounding; what remains is the rounding of
// the residual Phi(q) (a few eps times the terms' size, ~ the length scale) mapped through
// Phi_q^-1: kappa times a few eps. Velocities: one solve Phi_q qd = nu with Phi_q and nu exact
// to a few eps (plus the position error): again kappa times a few eps (forward error of a
// backward-stable LU: kappa * O(n eps)). Accelerations: gamma is quadratic in qd, so it
// inherits the velocity error once more before the solve; still kappa times a few eps for
// kappa of order ten, so the same form with a larger constant.
constexpr double kPositionFactor = 2;
constexpr double kVelocityFactor = 2;
constexpr double kAccelerationFactor = 4;

const std::vector<std::string>& example_files() {
  static const std::vector<std::string> files = [] {
    std::vector<std::string> f;
    for (const auto& e : fs::directory_iterator(fs::path(KINEGEN_SOURCE_DIR) / "examples"))
      if (e.path().extension() == ".yaml") f.push_back(e.path().string());
    std::sort(f.begin(), f.end());
    return f;
  }();
  return files;
}

std::unique_ptr<cg::CompiledModel> load(const std::string& name) {
  return cg::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/examples/" + name +
                                      ".yaml");
}

// |got - want| in double, the difference taken exactly.
double diff(double got, const numeric& want) {
  return std::abs((cg::exact_numeric(got) - want).to_double());
}

// cond_2 of Phi_q with columns scaled to [L, L, 1] per body (so lengths and angles weigh
// alike) and rows equilibrated (constraints in lengths and in angles alike).
double scaled_condition(const cg::CompiledModel& model, const Eigen::VectorXd& q, double t) {
  cg::ModelEvaluator<double> eval(model);
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(model.nc(), model.nq());
  eval.jacobian(q.data(), t, jac);
  for (int k = 0; k < model.nq(); ++k) jac.col(k) *= model.symbolic().coordinate_scales[k];
  for (int r = 0; r < model.nc(); ++r) jac.row(r) /= jac.row(r).cwiseAbs().maxCoeff();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(jac);
  const auto& s = svd.singularValues();
  return s(0) / s(s.size() - 1);
}

// Errors of one step, in ulps of each block's size (scaled: lengths / L, angles in rad).
struct StepError {
  double q = 0, qd = 0, qdd = 0;
};

StepError step_error(const cg::CompiledModel& model, const cg::ReferenceRow& ref,
                     const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                     const Eigen::VectorXd& qdd, const std::vector<cg::PointState>& points) {
  const auto& scales = model.symbolic().coordinate_scales;
  const auto block = [&](const std::vector<numeric>& want, const Eigen::VectorXd& got,
                         const auto& point_value, int point_slot) {
    double err = 0, size = 0;
    for (int k = 0; k < model.nq(); ++k) {
      const double s = scales[k];
      err = std::max(err, diff(got[k], want[k]) / s);
      size = std::max(size, std::abs(want[k].to_double()) / s);
    }
    for (std::size_t p = 0; p < points.size(); ++p)
      for (int c = 0; c < 2; ++c)
        err = std::max(err, diff(point_value(points[p])[c], ref.points[p][point_slot + c]) /
                                model.symbolic().length_scale);
    return err / (kEps * std::max(size, 1e-300));
  };
  StepError e;
  e.q = block(
      ref.q, q, [](const cg::PointState& p) { return p.r; }, 0);
  e.qd = block(
      ref.qd, qd, [](const cg::PointState& p) { return p.v; }, 2);
  e.qdd = block(
      ref.qdd, qdd, [](const cg::PointState& p) { return p.a; }, 4);
  return e;
}

struct RunSummary {
  double worst_q = 0, worst_qd = 0, worst_qdd = 0;                    // ulps
  double worst_ratio_q = 0, worst_ratio_qd = 0, worst_ratio_qdd = 0;  // ulps / kappa
  double max_kappa = 0;
  int rows = 0;
  int violations = 0;  // steps outside the bound
  std::string first_violation;
};

std::vector<cg::ReferenceRow> reference_run(const cg::CompiledModel& model, int steps, double t1) {
  std::vector<cg::ReferenceRow> rows;
  cg::run_reference_analysis_exact(model, {0.0, t1, steps}, kDigits,
                                   [&](const cg::ReferenceRow& r) { rows.push_back(r); });
  return rows;
}

// Compares double rows (q, qd, qdd, points) with the reference, asserting the bound per step.
RunSummary compare(const cg::CompiledModel& model, const std::vector<cg::ReferenceRow>& ref,
                   const std::vector<cg::StateRow>& got, const std::string& what) {
  REQUIRE(got.size() == ref.size());
  RunSummary s;
  for (std::size_t k = 0; k < ref.size(); ++k) {
    const cg::StateRow& row = got[k];
    REQUIRE(row.t == ref[k].t.to_double());
    const double kappa = scaled_condition(model, row.q, row.t);
    const StepError e = step_error(model, ref[k], row.q, row.qd, row.qdd, row.points);
    if (e.q > kPositionFactor * kappa || e.qd > kVelocityFactor * kappa ||
        e.qdd > kAccelerationFactor * kappa) {
      if (s.violations++ == 0)
        s.first_violation = what + " at t = " + cg::format_number(row.t) + ": kappa " +
                            std::to_string(kappa) + ", ulps q " + std::to_string(e.q) + ", qd " +
                            std::to_string(e.qd) + ", qdd " + std::to_string(e.qdd);
    }
    s.worst_q = std::max(s.worst_q, e.q);
    s.worst_qd = std::max(s.worst_qd, e.qd);
    s.worst_qdd = std::max(s.worst_qdd, e.qdd);
    s.worst_ratio_q = std::max(s.worst_ratio_q, e.q / kappa);
    s.worst_ratio_qd = std::max(s.worst_ratio_qd, e.qd / kappa);
    s.worst_ratio_qdd = std::max(s.worst_ratio_qdd, e.qdd / kappa);
    s.max_kappa = std::max(s.max_kappa, kappa);
    ++s.rows;
  }
  return s;
}

void print(const std::string& name, const std::string& what, const RunSummary& s) {
  std::printf(
      "accuracy %-22s %-28s kappa<=%6.2f  worst ulps q %5.2f qd %5.2f qdd %5.2f  "
      "(ulps/kappa %4.2f %4.2f %4.2f)\n",
      name.c_str(), what.c_str(), s.max_kappa, s.worst_q, s.worst_qd, s.worst_qdd, s.worst_ratio_q,
      s.worst_ratio_qd, s.worst_ratio_qdd);
  INFO(s.first_violation);
  CHECK(s.rows == kSteps + 1);
  CHECK(s.violations == 0);
}

// Solver<Model> on the committed header, each step from the previous solution (the first from
// q0), as a user drives it; points computed as the analysis does.
template <class Model>
std::vector<cg::StateRow> generated_run(const cg::CompiledModel& model, int steps, double t1,
                                        kinegen::SolverOptions options = {}) {
  kinegen::Solver<Model> solver(typename Model::Params{}, options);
  auto q = solver.initial_estimate();
  decltype(q) qd, qdd;
  const cg::TimeGrid grid{0.0, t1, steps};
  std::vector<cg::StateRow> rows;
  for (int k = 0; k <= steps; ++k) {
    const double t = grid.at(k);
    REQUIRE(solver.position(q, t));
    REQUIRE(solver.velocity(q, t, qd));
    REQUIRE(solver.acceleration(q, qd, t, qdd));
    cg::StateRow row;
    row.t = t;
    row.q = q;
    row.qd = qd;
    row.qdd = qdd;
    const auto& points = model.mechanism().points;
    for (std::size_t p = 0; p < points.size(); ++p) {
      const int b = 3 * points[p].body;
      row.points.push_back(cg::point_state(row.q.segment<3>(b), row.qd.segment<3>(b),
                                           row.qdd.segment<3>(b), model.point_offsets()[p]));
    }
    rows.push_back(row);
  }
  return rows;
}

template <class Model>
void check_example(const std::string& name) {
  const auto model = load(name);
  // A full crank turn: every example drives its crank at omega = 1.
  bool omega_one = false;
  for (const auto& [name, value] : model->parameter_table())
    omega_one = omega_one || (name == "omega" && value == 1.0);
  REQUIRE(omega_one);
  const auto ref = reference_run(*model, kSteps, kTurn);
  REQUIRE(ref.size() == kSteps + 1u);

  std::vector<cg::StateRow> analysis;
  cg::run_analysis(*model, {0.0, kTurn, kSteps},
                   [&](const cg::StateRow& r) { analysis.push_back(r); });
  print(name, "run_analysis", compare(*model, ref, analysis, name + " (run_analysis)"));
  print(name, "Solver<Model>",
        compare(*model, ref, generated_run<Model>(*model, kSteps, kTurn), name + " (generated)"));
  kinegen::SolverOptions tight;
  tight.tolerance = 1e-14;
  print(name, "Solver<Model> tol 1e-14",
        compare(*model, ref, generated_run<Model>(*model, kSteps, kTurn, tight),
                name + " (generated, tol 1e-14)"));
}

}  // namespace

TEST_CASE("the examples are the ones with a generated header here", "[reference]") {
  std::vector<std::string> names;
  for (const auto& f : example_files()) names.push_back(fs::path(f).stem().string());
  CHECK(names == std::vector<std::string>{"four_bar", "offset_slider_crank", "quick_return",
                                          "slider_crank", "slider_crank_lecture"});
}

TEST_CASE("double analysis of four_bar within the stated bound of its 40-digit reference",
          "[reference][bound]") {
  check_example<kinegen::models::four_bar>("four_bar");
}
TEST_CASE("double analysis of offset_slider_crank within the stated bound of its reference",
          "[reference][bound]") {
  check_example<kinegen::models::offset_slider_crank>("offset_slider_crank");
}
TEST_CASE("double analysis of quick_return within the stated bound of its reference",
          "[reference][bound]") {
  check_example<kinegen::models::quick_return>("quick_return");
}
TEST_CASE("double analysis of slider_crank within the stated bound of its reference",
          "[reference][bound]") {
  check_example<kinegen::models::slider_crank>("slider_crank");
}
TEST_CASE("double analysis of slider_crank_lecture within the stated bound of its reference",
          "[reference][bound]") {
  check_example<kinegen::models::slider_crank_lecture>("slider_crank_lecture");
}

TEST_CASE("the bound comparison detects a reference of another mechanism", "[reference]") {
  // The reference of a rocker longer by 1e-9 (relative 4e-10): far above rounding, far below
  // anything a plot would show.
  const auto model = load("four_bar");
  const auto other = cg::CompiledModel::from_file(
      std::string(KINEGEN_SOURCE_DIR) + "/examples/four_bar.yaml", {{"c", "2.500000001"}});
  const auto ref = reference_run(*other, 36, kTurn);
  std::vector<cg::StateRow> rows;
  cg::run_analysis(*model, {0.0, kTurn, 36}, [&](const cg::StateRow& r) { rows.push_back(r); });
  const RunSummary s = compare(*model, ref, rows, "four_bar against c + 1e-9");
  CHECK(s.violations > 0);
  CHECK(s.worst_q > 1e3);
}

TEST_CASE("reference digits outside [20, 1000] are a usage error", "[reference]") {
  const auto model = load("four_bar");
  const auto sink = [](const cg::StateRow&) {};
  CHECK_THROWS_AS(cg::run_reference_analysis(*model, {0, 1, 2}, 19, sink), cg::UsageError);
  CHECK_THROWS_AS(cg::run_reference_analysis(*model, {0, 1, 2}, 1001, sink), cg::UsageError);
}

TEST_CASE("the 40-digit reference agrees with a 60-digit one to 1e-36", "[reference]") {
  const auto model = load("quick_return");
  const auto a = reference_run(*model, 12, kTurn);
  std::vector<cg::ReferenceRow> b;
  cg::run_reference_analysis_exact(*model, {0.0, kTurn, 12}, 60,
                                   [&](const cg::ReferenceRow& r) { b.push_back(r); });
  REQUIRE(a.size() == b.size());
  double worst = 0;
  for (std::size_t k = 0; k < a.size(); ++k)
    for (int i = 0; i < model->nq(); ++i)
      for (auto v : {&cg::ReferenceRow::q, &cg::ReferenceRow::qd, &cg::ReferenceRow::qdd})
        worst = std::max(worst, GiNaC::abs((a[k].*v)[i] - (b[k].*v)[i]).to_double());
  INFO("largest difference " << worst);
  CHECK(worst < 1e-36);
}

// Closed forms of the examples' positions as GiNaC expressions of t (the branches of
// tests/support/closed_form.hpp, the files' parameters), velocities and accelerations by
// GiNaC's diff: a derivation independent of both the reference and the double path.
namespace {

std::vector<ex> closed_form_q(const std::string& name, const ex& t) {
  using GiNaC::acos;
  using GiNaC::asin;
  using GiNaC::cos;
  using GiNaC::sin;
  const ex zero = 0;
  if (name == "slider_crank" || name == "slider_crank_lecture") {
    const ex l = 2, p2 = acos(sin(t) / l);
    return {zero, zero, t, cos(t) + l * sin(p2), zero, p2};
  }
  if (name == "offset_slider_crank") {
    const ex r = 1, l = 3, e = numeric(1, 2);
    const ex p2 = asin((e - r * sin(t)) / l);
    return {zero, zero, t, r * cos(t), r * sin(t), p2, r * cos(t) + l * cos(p2), e, zero};
  }
  if (name == "four_bar") {
    const ex a = 1, b = numeric(7, 2), c = numeric(5, 2), d = 3;
    const ex dx = d - a * cos(t), dy = -a * sin(t), del2 = dx * dx + dy * dy;
    const ex del = GiNaC::sqrt(del2);
    const ex theta = GiNaC::atan(dy / dx);  // dx >= d - a > 0
    const ex alpha = acos((b * b + del2 - c * c) / (2 * b * del));
    const ex beta = acos((c * c + del2 - b * b) / (2 * c * del));
    return {
        zero, zero, t, a * cos(t), a * sin(t), theta + alpha, d, zero, theta + GiNaC::Pi - beta};
  }
  if (name == "quick_return") {
    const ex r = 1, d = 2, p3 = GiNaC::atan2(d + r * sin(t), r * cos(t));
    return {zero, zero, t, zero, -d, p3, r * cos(t), r * sin(t), p3};
  }
  FAIL("no closed form for " << name);
  return {};
}

}  // namespace

TEST_CASE("the 40-digit reference agrees with the closed forms to 1e-30", "[reference]") {
  for (const auto& file : example_files()) {
    const std::string name = fs::path(file).stem().string();
    INFO(name);
    const auto model = load(name);
    const GiNaC::realsymbol t("t");
    const std::vector<ex> q = closed_form_q(name, t);
    REQUIRE(static_cast<int>(q.size()) == model->nq());
    std::vector<ex> qd, qdd;
    for (const ex& e : q) qd.push_back(e.diff(t));
    for (const ex& e : qd) qdd.push_back(e.diff(t));
    const auto ref = reference_run(*model, 24, kTurn);
    const cg::DigitsGuard digits(50);
    double worst = 0;
    for (const auto& row : ref) {
      const GiNaC::exmap at{{t, row.t}};
      for (int i = 0; i < model->nq(); ++i) {
        const auto value = [&](const ex& e) { return GiNaC::ex_to<numeric>(e.subs(at).evalf()); };
        worst = std::max({worst, GiNaC::abs(row.q[i] - value(q[i])).to_double(),
                          GiNaC::abs(row.qd[i] - value(qd[i])).to_double(),
                          GiNaC::abs(row.qdd[i] - value(qdd[i])).to_double()});
      }
    }
    std::printf("accuracy %-22s reference vs GiNaC closed form: largest difference %.2e\n",
                name.c_str(), worst);
    CHECK(worst < 1e-30);
  }
}

TEST_CASE("the reference gives the same digits in every process", "[reference]") {
  // GiNaC orders a sum's and a product's operands by hashes that mix in addresses, which
  // differ between processes: evaluated in that order, the last digits of the reference (and
  // the tiny residues of values that are exactly 0) changed from run to run. Separate
  // processes, as only they can differ in hash order.
  constexpr int kRuns = 8;
  const fs::path examples = fs::path(KINEGEN_SOURCE_DIR) / "examples";
  const std::vector<std::vector<std::string>> commands = {
      {"four_bar.yaml", "--t1", "1", "--steps", "2", "--reference-digits", "30"},
      {"gears/planetary.yaml", "--t1", "3", "--steps", "6", "--reference-digits", "40"},
      {"cams/disc_cam.yaml", "--t1", "3", "--steps", "6", "--reference-digits", "40"},
      {"forces/four_bar_balanced.yaml", "--t1", "1", "--steps", "4", "--reference-digits", "30",
       "--forces"}};
  for (const auto& command : commands) {
    INFO(command[0]);
    std::vector<std::string> args = {KINEGEN_EXE, "analyze", (examples / command[0]).string(),
                                     "--t0", "0"};
    args.insert(args.end(), command.begin() + 1, command.end());
    std::string first;
    for (int run = 0; run < kRuns; ++run) {
      const auto r = kinegen::test::run_command(args);
      INFO(r.err);
      REQUIRE(r.exit_code == 0);
      if (run == 0)
        first = r.out;
      else
        CHECK(r.out == first);  // a failure means some sum or product follows GiNaC's order
    }
  }
}
