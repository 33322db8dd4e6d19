// First solves and branches (docs/embedding.md): a fresh generated Solver asked for its first
// position() or step() at a time where q0 does not fit follows the drivers there from the q0
// pose, and lands on the assembly that the motion from t = 0 reaches, never on another one
// with success. The truth is `kinegen analyze` (run_analysis) continued from t = 0 along the
// motion in small steps; the command line's own first solve at t (analyze --t0 t) must agree.
// The same for the generated dynamics() with a fresh work space, against `kinegen simulate`.
#include <catch2/catch.hpp>
#include <cmath>
#include <kinegen/block_solver.hpp>
#include <string>
#include <vector>

#include "cam_liftoff.hpp"
#include "cam_roller.hpp"
#include "disc_cam.hpp"
#include "drag_link.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/simulate.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "planetary.hpp"

namespace {

namespace cg = kinegen::codegen;
constexpr double kTwoPi = 6.283185307179586;
constexpr int kTimes = 25;

std::string source(const std::string& path) { return std::string(KINEGEN_SOURCE_DIR) + path; }

// q at t_i = t1 i / kTimes (i = 1..kTimes) by analyze from t = 0 along the motion, in steps of
// t1 / (kTimes * per_time).
std::vector<Eigen::VectorXd> continued_truth(const std::string& file, double t1, int per_time) {
  const auto model = cg::CompiledModel::from_file(file);
  std::vector<Eigen::VectorXd> truth;
  int row = 0;
  cg::run_analysis(*model, {0.0, t1, kTimes * per_time}, [&](const cg::StateRow& r) {
    if (row > 0 && row % per_time == 0) truth.push_back(r.q);
    ++row;
  });
  REQUIRE(static_cast<int>(truth.size()) == kTimes);
  return truth;
}

// |a - b| over the coordinates.
template <class A, class B>
double difference(const A& a, const B& b) {
  double worst = 0;
  for (int k = 0; k < a.size(); ++k) worst = std::max(worst, std::abs(a[k] - b[k]));
  return worst;
}

// Each time from a fresh Solver (position(), then step()) and from analyze started there: the
// answers that succeed equal the continued truth to 1e-9 (a failure must say why); returns how
// many succeeded.
template <class M>
int fresh_first_solves(const std::string& file, double t1, int per_time) {
  const auto truth = continued_truth(file, t1, per_time);
  const auto model = cg::CompiledModel::from_file(file);
  int solved = 0;
  for (int i = 1; i <= kTimes; ++i) {
    const double t = t1 * i / kTimes;
    INFO("t = " << t);
    const Eigen::VectorXd& exact = truth[i - 1];
    {
      kinegen::Solver<M> solver;
      auto q = solver.initial_estimate();
      const kinegen::Result r = solver.position(q, t);
      INFO("position(): " << r.message());
      if (r) {
        CHECK(difference(q, exact) < 1e-9);
        ++solved;
      } else {
        CHECK(r.status != kinegen::Status::kConverged);
      }
    }
    {
      kinegen::Solver<M> solver;
      auto q = solver.initial_estimate();
      typename kinegen::Solver<M>::Vector qd, qdd;
      const kinegen::Result r = solver.step(t, q, qd, qdd);
      INFO("step(): " << r.message());
      if (r) {
        CHECK(difference(q, exact) < 1e-9);
        ++solved;
      }
    }
    // analyze --t0 t: the command line's own first solve.
    bool analyzed = false;
    try {
      cg::run_analysis(*model, {t, t, 0}, [&](const cg::StateRow& r) {
        CHECK(difference(r.q, exact) < 1e-9);
        analyzed = true;
      });
    } catch (const std::exception& e) {
      INFO("analyze --t0: " << e.what());
    }
    solved += analyzed;
  }
  return solved;
}

}  // namespace

TEST_CASE("first solves: the disc cam at 25 times of a turn lands on the motion's assembly",
          "[first-solve]") {
  CHECK(fresh_first_solves<kinegen::models::disc_cam>(source("/examples/cams/disc_cam.yaml"),
                                                      kTwoPi, 8) == 3 * kTimes);
}

TEST_CASE("first solves: the planetary train over six sun turns lands on the motion's assembly",
          "[first-solve]") {
  CHECK(fresh_first_solves<kinegen::models::planetary>(source("/examples/gears/planetary.yaml"),
                                                       kTwoPi, 16) == 3 * kTimes);
}

TEST_CASE("first solves: a drag-link and a roller cam over a turn", "[first-solve]") {
  CHECK(fresh_first_solves<kinegen::models::drag_link>(source("/tests/mechanisms/drag_link.yaml"),
                                                       kTwoPi, 8) == 3 * kTimes);
  CHECK(fresh_first_solves<kinegen::models::cam_roller>(source("/tests/mechanisms/cam_roller.yaml"),
                                                        kTwoPi / 2, 8) == 3 * kTimes);
}

TEST_CASE("first solves: a driver far beyond the start pose is a refusal with a status",
          "[first-solve]") {
  // 1e6 turns of the cam from q0: more continuation steps than the solver takes.
  kinegen::Solver<kinegen::models::disc_cam> solver;
  auto q = solver.initial_estimate();
  const kinegen::Result r = solver.position(q, 1e6 * kTwoPi);
  CHECK(r.status == kinegen::Status::kTooFar);
  CHECK(std::string(r.message()).find("start pose") != std::string::npos);
}

TEST_CASE("first solves: reset() makes the next step a first solve again", "[first-solve]") {
  using M = kinegen::models::disc_cam;
  const auto truth = continued_truth(source("/examples/cams/disc_cam.yaml"), kTwoPi, 8);
  kinegen::Solver<M> solver;
  typename kinegen::Solver<M>::Vector q = solver.initial_estimate(), qd, qdd;
  REQUIRE(solver.step(0.0, q, qd, qdd));
  solver.reset();
  q = solver.initial_estimate();
  const double t = kTwoPi * 17 / kTimes;
  REQUIRE(solver.step(t, q, qd, qdd));
  CHECK(difference(q, truth[16]) < 1e-9);
}

// The rows of `kinegen simulate --t1 0.5 --steps 20` on the cam with lift-off, each fed to the
// header's dynamics() with a fresh work space, and along the rows with one work space kept:
// the same zdd as the command line's (which continues its motion row by row).
TEST_CASE(
    "first solves: cam_liftoff dynamics() from a fresh or a kept work space matches "
    "simulate's rows",
    "[first-solve]") {
  using M = kinegen::models::cam_liftoff;
  cg::BuildOptions build;
  build.free_as_state = true;
  const auto model =
      cg::CompiledModel::from_file(source("/examples/dynamics/cam_liftoff.yaml"), {}, build);
  const cg::ForceModel forces = cg::derive_forces(*model);
  std::vector<cg::SimulatedRow> rows;
  cg::run_simulation(
      *model, forces, {0.0, 0.5, 20}, [&](const cg::SimulatedRow& r) { rows.push_back(r); },
      cg::SimulateOptions{});
  REQUIRE(rows.size() == 21);
  M::DynamicsWork<double> kept;
  for (const auto& row : rows) {
    INFO("t = " << row.state.t);
    const double scale = std::max(1.0, row.zdd.cwiseAbs().maxCoeff());
    double zdd[M::nf];
    M::DynamicsWork<double> fresh;
    const auto r = M::dynamics(row.z.data(), row.zd.data(), row.state.t, M::Params{}, zdd,
                               M::BlockOptions{}, fresh);
    REQUIRE(r.status == 0);
    for (int k = 0; k < M::nf; ++k) CHECK(std::abs(zdd[k] - row.zdd[k]) < 1e-8 * scale);
    CHECK(difference(Eigen::Map<const Eigen::VectorXd>(fresh.q, M::nq), row.state.q) < 1e-9);
    const auto rk = M::dynamics(row.z.data(), row.zd.data(), row.state.t, M::Params{}, zdd,
                                M::BlockOptions{}, kept);
    REQUIRE(rk.status == 0);
    for (int k = 0; k < M::nf; ++k) CHECK(std::abs(zdd[k] - row.zdd[k]) < 1e-8 * scale);
  }
}
