// The sparse path of the in-process analysis (kinegen/sparse_solver.hpp): large square models
// factor Phi_q with a sparse LU instead of a dense one. Checked against the dense path, against
// the closed forms of the scalable families (scripts/mechanism_family.py), against the exact
// 1-norm condition number, and on failures.
#include <Eigen/Dense>
#include <algorithm>
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <kinegen/solver.hpp>
#include <kinegen/sparse_solver.hpp>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/structure/structure.hpp"
#include "support/run_command.hpp"

namespace {

namespace cg = kinegen::codegen;
namespace fs = std::filesystem;

const double kPi = std::acos(-1.0);

// A member of a scalable family, written by the project's own script into the test scratch
// directory (once per family and size).
std::string family_file(const std::string& family, int n) {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "sparse";
  fs::create_directories(dir);
  const fs::path file = dir / (family + "_" + std::to_string(n) + ".yaml");
  if (!fs::exists(file)) {
    const std::string command = "python3 '" + std::string(KINEGEN_SOURCE_DIR) +
                                "/scripts/mechanism_family.py' " + family + " " +
                                std::to_string(n) + " -o '" + file.string() + ".part'";
    REQUIRE(std::system(command.c_str()) == 0);
    fs::rename(file.string() + ".part", file);
  }
  return file.string();
}

std::vector<cg::StateRow> analyze(const cg::CompiledModel& model, const cg::TimeGrid& grid,
                                  int sparse_above_nq) {
  cg::AnalysisOptions options;
  options.block_solver = false;  // the dense and the sparse Newton, not the block program
  options.sparse_above_nq = sparse_above_nq;
  std::vector<cg::StateRow> rows;
  cg::run_analysis(
      model, grid, [&](const cg::StateRow& r) { rows.push_back(r); }, options);
  return rows;
}

constexpr int kAlwaysSparse = 0;
constexpr int kAlwaysDense = std::numeric_limits<int>::max();

// Largest |a - b| / (1 + |a|) over every q, qd, qdd of every row.
double max_difference(const std::vector<cg::StateRow>& a, const std::vector<cg::StateRow>& b) {
  REQUIRE(a.size() == b.size());
  double worst = 0;
  for (std::size_t k = 0; k < a.size(); ++k)
    for (const auto member : {&cg::StateRow::q, &cg::StateRow::qd, &cg::StateRow::qdd}) {
      const Eigen::VectorXd& x = a[k].*member;
      const Eigen::VectorXd& y = b[k].*member;
      worst = std::max(worst, ((x - y).array().abs() / (1 + x.array().abs())).maxCoeff());
    }
  return worst;
}

// The exact 1-norm condition number of Phi_q as the solvers scale it (rows equilibrated by
// their largest entry, columns times their coordinate's scale), from a dense inverse.
double exact_condition(const cg::CompiledModel& model, const Eigen::VectorXd& q, double t) {
  cg::ModelEvaluator<double> eval(model);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(model.nc(), model.nq());
  eval.jacobian(q.data(), t, a);
  for (int k = 0; k < a.cols(); ++k) a.col(k) *= model.symbolic().coordinate_scales[k];
  for (int r = 0; r < a.rows(); ++r) a.row(r) /= a.row(r).cwiseAbs().maxCoeff();
  const auto norm1 = [](const Eigen::MatrixXd& m) {
    return m.cwiseAbs().colwise().sum().maxCoeff();
  };
  return norm1(a) * norm1(a.inverse());
}

// A linear system Phi = A q - t 1 on a random sparse A (diagonally dominant unless a row is
// zeroed): Newton solves it in one step, and every answer has an exact dense counterpart.
struct LinearSystem {
  using Scalar = double;
  int n = 0;
  std::vector<int> rows, cols;
  std::vector<double> values;
  int nq() const { return n; }
  int nc() const { return n; }
  double length_scale() const { return 2.0; }
  void phi(const double* q, double t, double* out) const {
    for (int i = 0; i < n; ++i) out[i] = -t;
    for (std::size_t k = 0; k < rows.size(); ++k) out[rows[k]] += values[k] * q[cols[k]];
  }
  void nu(const double*, double, double* out) const { std::fill(out, out + n, 1.0); }
  void gamma(const double*, const double*, double, double* out) const {
    std::fill(out, out + n, 0.0);
  }
  int jacobian_nnz() const { return static_cast<int>(rows.size()); }
  const int* jacobian_rows() const { return rows.data(); }
  const int* jacobian_cols() const { return cols.data(); }
  void jacobian_values(const double*, double, double* out) const {
    std::copy(values.begin(), values.end(), out);
  }
  Eigen::MatrixXd dense() const {
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
    for (std::size_t k = 0; k < rows.size(); ++k) a(rows[k], cols[k]) = values[k];
    return a;
  }
};

LinearSystem random_system(int n, unsigned seed) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  LinearSystem s;
  s.n = n;
  for (int i = 0; i < n; ++i) {
    // A random sign on the diagonal makes det's sign vary from seed to seed.
    s.rows.push_back(i);
    s.cols.push_back(i);
    s.values.push_back((u(gen) < 0 ? -1 : 1) * (4 + u(gen)));
    const int j1 = (7 * i + 3) % n, j2 = (13 * i + 5) % n;  // entries are distinct
    for (int j : {j1, j2})
      if (j != i && !(j == j2 && j2 == j1)) {
        s.rows.push_back(i);
        s.cols.push_back(j);
        s.values.push_back(u(gen));
      }
  }
  return s;
}

}  // namespace

TEST_CASE("SparseSolver on a random sparse linear system", "[sparse]") {
  for (unsigned seed = 1; seed <= 6; ++seed) {
    INFO("seed " << seed);
    const LinearSystem system = random_system(200, seed);
    const Eigen::MatrixXd a = system.dense();
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(a);
    kinegen::SparseSolver<LinearSystem> solver{system};
    Eigen::VectorXd q = Eigen::VectorXd::Zero(system.n), qd(system.n), qdd(system.n);
    const double t = 1.5;
    REQUIRE(solver.position(q, t));
    REQUIRE(solver.velocity(q, t, qd));
    REQUIRE(solver.acceleration(q, qd, t, qdd));
    const Eigen::VectorXd ones = Eigen::VectorXd::Ones(system.n);
    CHECK((q - lu.solve(t * ones)).cwiseAbs().maxCoeff() < 1e-14);
    CHECK((qd - lu.solve(ones)).cwiseAbs().maxCoeff() < 1e-14);
    CHECK(qdd.cwiseAbs().maxCoeff() == 0);
    CHECK(solver.jacobian_sign() == (lu.determinant() > 0 ? 1 : -1));
  }
  // A zero row: structurally rank deficient, reported as singular, never a solution.
  LinearSystem system = random_system(200, 1);
  for (std::size_t k = 0; k < system.rows.size(); ++k)
    if (system.rows[k] == 17) system.values[k] = 0;
  kinegen::SparseSolver<LinearSystem> solver{system};
  Eigen::VectorXd q = Eigen::VectorXd::Zero(system.n);
  const auto r = solver.position(q, 1.0);
  CHECK(r.status == kinegen::Status::kSingular);
  CHECK(r.condition == std::numeric_limits<double>::infinity());
  CHECK(solver.jacobian_sign() == 0);
}

TEST_CASE("sparse and dense paths agree on every family", "[sparse]") {
  // nq = 93, 72, 75: moderate sizes where both paths are quick.
  for (const auto& [family, n] : {std::pair<std::string, int>{"fourbar_chain", 15},
                                  {"scissor_lift", 12},
                                  {"closed_chain", 25}}) {
    INFO(family << " " << n);
    const auto model = cg::CompiledModel::from_file(family_file(family, n));
    const cg::TimeGrid grid{0, 2 * kPi, 48};
    const auto sparse = analyze(*model, grid, kAlwaysSparse);
    const auto dense = analyze(*model, grid, kAlwaysDense);
    const double difference = max_difference(sparse, dense);
    CHECK(difference < 1e-13);
  }
}

TEST_CASE("small models stay on the dense path by default", "[sparse]") {
  // fourbar_chain 7 (nq = 45) is below the default threshold: bit-identical to the dense path.
  const auto model = cg::CompiledModel::from_file(family_file("fourbar_chain", 7));
  REQUIRE(model->nq() <= cg::AnalysisOptions{}.sparse_above_nq);
  const cg::TimeGrid grid{0, 2 * kPi, 12};
  CHECK(max_difference(analyze(*model, grid, cg::AnalysisOptions{}.sparse_above_nq),
                       analyze(*model, grid, kAlwaysDense)) == 0);
}

TEST_CASE("a chain of 300 four-bar loops follows its closed form on the sparse path", "[sparse]") {
  const int n = 300;  // nq = 1803: a dense LU per step would take a good fraction of a second
  const auto model = cg::CompiledModel::from_file(family_file("fourbar_chain", n));
  REQUIRE(model->nq() == 6 * n + 3);
  REQUIRE(model->nq() > cg::AnalysisOptions{}.sparse_above_nq);
  const double c = 1.0, d = 1.5, amp = 0.5, omega = 1.0;
  const cg::TimeGrid grid{0, 2 * kPi, 24};
  const auto rows = analyze(*model, grid, cg::AnalysisOptions{}.sparse_above_nq);
  REQUIRE(rows.size() == 25);
  double worst = 0;
  for (const auto& row : rows) {
    const double t = row.t;
    const double phi = kPi / 2 + amp * std::sin(omega * t);
    const double w = amp * omega * std::cos(omega * t);
    const double alpha = -amp * omega * omega * std::sin(omega * t);
    const auto check = [&](double got, double want) {
      worst = std::max(worst, std::abs(got - want));
    };
    // Bodies: crank, then (coupler_k, rocker_k) for k = 0..n-1; every side link keeps the
    // crank's angle, couplers stay level at the tips' height.
    for (int b = 0; b < 2 * n + 1; ++b) {
      const bool coupler = b % 2 == 1;
      const int k = (b - 1) / 2;  // loop index of coupler / rocker
      const double x0 = coupler ? k * d : (b == 0 ? 0.0 : (k + 1) * d);
      if (coupler) {
        // Origin at the input link's tip.
        check(row.q[3 * b], x0 + c * std::cos(phi));
        check(row.q[3 * b + 1], c * std::sin(phi));
        check(row.q[3 * b + 2], 0);
        check(row.qd[3 * b], -c * std::sin(phi) * w);
        check(row.qd[3 * b + 1], c * std::cos(phi) * w);
        check(row.qdd[3 * b], -c * std::cos(phi) * w * w - c * std::sin(phi) * alpha);
        check(row.qdd[3 * b + 1], -c * std::sin(phi) * w * w + c * std::cos(phi) * alpha);
        check(row.qdd[3 * b + 2], 0);
      } else {
        check(row.q[3 * b], x0);
        check(row.q[3 * b + 1], 0);
        check(row.q[3 * b + 2], phi);
        check(row.qd[3 * b + 2], w);
        check(row.qdd[3 * b + 2], alpha);
      }
    }
  }
  CHECK(worst < 1e-10);
}

TEST_CASE("sparse condition estimate and det sign match the dense ones", "[sparse]") {
  const auto model = cg::CompiledModel::from_file(family_file("scissor_lift", 12));  // nq = 72
  kinegen::BasicSolver<cg::ProgramSystem> dense{cg::ProgramSystem(*model)};
  kinegen::SparseSolver<cg::ProgramSystem> sparse{cg::ProgramSystem(*model)};
  CHECK(sparse.jacobian_nonzeros() < model->nq() * model->nq() / 10);
  for (double t : {0.0, 0.7, 2.0, 4.5}) {
    INFO("t = " << t);
    Eigen::VectorXd qa = model->q0(), qb = model->q0();
    REQUIRE(dense.position(qa, t));
    REQUIRE(sparse.position(qb, t));
    Eigen::VectorXd qda(qa.size()), qdb(qb.size());
    const auto ra = dense.velocity(qa, t, qda);
    const auto rb = sparse.velocity(qb, t, qdb);
    REQUIRE(ra);
    REQUIRE(rb);
    // Hager's estimate is a lower bound of the 1-norm condition number, usually close to it.
    const double exact = exact_condition(*model, qb, t);
    CHECK(rb.condition <= exact * (1 + 1e-8));
    CHECK(rb.condition >= exact / 3);
    CHECK(rb.condition >= ra.condition / 3);
    CHECK(rb.condition <= ra.condition * 3);
    CHECK(rb.rank == model->nq());
    CHECK(rb.pivot_ratio > 0);
    // det(Phi_q)'s sign, from an independent dense LU.
    Eigen::MatrixXd jac = Eigen::MatrixXd(sparse.jacobian());
    const double det = Eigen::PartialPivLU<Eigen::MatrixXd>(jac).determinant();
    CHECK(sparse.jacobian_sign() == (det > 0 ? 1 : -1));
    CHECK(dense.jacobian_sign() == sparse.jacobian_sign());
  }
}

TEST_CASE("the sparse path reports a scissor lift driven past its reach", "[sparse]") {
  // w = w0 + dw sin(t) with w0 = 0.9, dw = 0.2 passes w = l = 1 (bars flat) at t = pi / 6:
  // t = 0.5 still assembles, t = 0.55 (w = 1.0045) cannot; the sub-steps between stop at
  // pi / 6, within 1/4096 of the step.
  const std::string file = family_file("scissor_lift", 40);  // nq = 240
  const auto r = kinegen::test::run_command({KINEGEN_EXE, "analyze", file, "--param", "w0=0.9",
                                             "--t0", "0", "--t1", "1", "--steps", "20"});
  INFO(r.err);
  CHECK(r.exit_code == 1);
  const auto at = r.err.find("position analysis failed at t = ");
  REQUIRE(at != std::string::npos);
  const double t = std::stod(r.err.substr(at + 32));
  CHECK(t >= std::asin(0.5) - 0.05 / 4096);
  CHECK(t <= std::asin(0.5) + 0.05 / 4096);
  CHECK(r.err.find("(in sub-steps of the step from t = 0.5 to t = 0.55000000000000004") !=
        std::string::npos);
  CHECK(r.out.find("\n0.5,") != std::string::npos);  // the rows before it were written
  CHECK(r.out.find("\n0.55") == std::string::npos);
}

TEST_CASE("the sparse path reports a singular Phi_q (scissor bars flat)", "[sparse]") {
  // w0 = l, dw = 0: the bars lie flat, Phi_q is singular at the solution. Below the diagnosis
  // limit the constraints involved are named; above it, said to be too many. The block path
  // (the default) converges onto it only linearly, to a block condition of about sqrt(eps):
  // the Newton policy calls that singular too, and names the failed block's constraints.
  for (int n : {40, 120}) {  // nq = 240, 720
    for (const std::string solver : {"dense", "block"}) {
      INFO("N = " << n << ", --solver " << solver);
      const std::string file = family_file("scissor_lift", n);
      const auto r = kinegen::test::run_command({KINEGEN_EXE, "analyze", file, "--param", "w0=1",
                                                 "--param", "dw=0", "--t0", "0", "--t1", "1",
                                                 "--steps", "2", "--solver", solver});
      INFO(r.err);
      CHECK(r.exit_code == 1);
      CHECK(r.err.find("position analysis failed at t = 0: the constraint Jacobian Phi_q is "
                       "singular (condition estimate ") != std::string::npos);
      if (solver == "block") {
        CHECK(r.err.find("; involved: joints[0] (revolute)") != std::string::npos);
        CHECK(r.err.find("; block 0 of the block solver") != std::string::npos);
      } else if (n == 40) {
        CHECK(r.err.find("; involved: joints[0] (revolute)") != std::string::npos);
      } else {
        CHECK(r.err.find("720 coordinates are too many to name") != std::string::npos);
      }
    }
  }
  // In process, forced onto the sparse path at a small size.
  const auto model =
      cg::CompiledModel::from_file(family_file("scissor_lift", 12), {{"w0", "1"}, {"dw", "0"}});
  cg::AnalysisOptions options;
  options.block_solver = false;
  options.sparse_above_nq = kAlwaysSparse;
  CHECK_THROWS_WITH(cg::run_analysis(
                        *model, cg::TimeGrid{0, 1, 2}, [](const cg::StateRow&) {}, options),
                    Catch::Contains("Phi_q is singular"));
  // The factorization itself: a Jacobian with exactly flat bars is singular.
  kinegen::SparseSolver<cg::ProgramSystem> sparse{cg::ProgramSystem(*model)};
  Eigen::VectorXd q = model->q0();
  for (int b = 0; b < model->nq() / 3; ++b) {  // every bar flat at the height of its stage
    q[3 * b + 2] = b % 2 == 0 ? 0.0 : kPi;
    q[3 * b] = 0.5;
    q[3 * b + 1] = 0.0;
  }
  Eigen::VectorXd qd(q.size());
  const auto rv = sparse.velocity(q, 0.0, qd);
  CHECK(rv.status == kinegen::Status::kSingular);
  CHECK(rv.rank < model->nq());
}

// Not a test: ms per step, dense against sparse. Run: kinegen_tests "[.sparse_bench]" -s
// (the dense path at nq = 6000 takes over a minute per step: only with KINEGEN_BENCH_DENSE_LARGE
// set in the environment).
TEST_CASE("sparse analysis timings", "[.sparse_bench]") {
  const bool dense_large = std::getenv("KINEGEN_BENCH_DENSE_LARGE") != nullptr;
  for (const auto& [family, n] : {std::pair<std::string, int>{"fourbar_chain", 1},
                                  {"fourbar_chain", 3},
                                  {"fourbar_chain", 5},
                                  {"fourbar_chain", 8},
                                  {"fourbar_chain", 10},
                                  {"fourbar_chain", 100},
                                  {"fourbar_chain", 1000},
                                  {"scissor_lift", 4},
                                  {"scissor_lift", 8},
                                  {"scissor_lift", 100},
                                  {"scissor_lift", 1000},
                                  {"closed_chain", 10},
                                  {"closed_chain", 20},
                                  {"closed_chain", 200}}) {
    const auto model = cg::CompiledModel::from_file(family_file(family, n));
    for (const bool dense : {true, false}) {
      if (dense && model->nq() > 3000 && !dense_large) continue;
      const int steps = dense && model->nq() > 3000 ? 1 : 50;
      const cg::TimeGrid grid{0, 2 * kPi * steps / 50.0, steps};
      int repeats = 0;
      double ms = 0;
      const auto start = std::chrono::steady_clock::now();
      do {  // at least 0.2 s of work for the small ones
        analyze(*model, grid, dense ? kAlwaysDense : kAlwaysSparse);
        ++repeats;
        ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                 .count();
      } while (ms < 200);
      std::printf("%-14s N = %4d  nq = %5d  %-6s  %10.4f ms/step (%d steps + t0, %d runs)\n",
                  family.c_str(), n, model->nq(), dense ? "dense" : "sparse",
                  ms / repeats / (steps + 1), steps, repeats);
    }
  }
}

TEST_CASE("a failed block's diagnosis names that block's constraints only", "[sparse]") {
  // Bars flat: every stage of the lift is singular, but the block solver stops at the first
  // failed block, with the later blocks' coordinates not yet solved for this time. Only the
  // failed block's rows may be named (all of Phi_q would name every stage's joints).
  const auto model =
      cg::CompiledModel::from_file(family_file("scissor_lift", 12), {{"w0", "1"}, {"dw", "0"}});
  std::string message;
  try {
    cg::run_analysis(*model, cg::TimeGrid{0, 1, 2}, [](const cg::StateRow&) {});
  } catch (const cg::AnalysisError& e) {
    message = e.what();
  }
  INFO(message);
  REQUIRE(message.find("Phi_q is singular") != std::string::npos);
  const std::string tag = "; block ";
  const auto at = message.find(tag);
  REQUIRE(at != std::string::npos);
  const int block = std::stoi(message.substr(at + tag.size()));
  const auto& plans = model->structure().plans;
  REQUIRE(block >= 0);
  REQUIRE(block < static_cast<int>(plans.size()));
  const auto& own = plans[block].block.rows;
  int named = 0;
  for (int r = 0; r < model->nc(); ++r) {
    const std::string label = model->row_label(r);
    if (message.find(label + ";") == std::string::npos &&
        message.find(label + ")") == std::string::npos)
      continue;
    ++named;
    INFO(label);
    CHECK(std::find(own.begin(), own.end(), r) != own.end());
  }
  CHECK(named > 0);
}
