// Time per full analysis step (position to the solver's tolerance, then velocity and
// acceleration) for each example, all measured in this one process on the same time grid:
//
//   block+pred   kinegen::Solver<Model>::step: the generated block solver (BLT order, explicit
//                blocks, Newton on the rest), with the Taylor predictor
//   block        the same block solver through position/velocity/acceleration, Newton from
//                the previous solution (no predictor)
//   fixed-1      step() with SolverOptions::fixed_iterations = 1 (one Newton iteration per
//                block, no convergence test: the real-time setting)
//   dense        kinegen::DenseSolver<Model>: dense Newton with the generated analytic Phi_q
//                and one LU of the whole matrix (the previous default path)
//   in-process   BlockInterpreter::solve_step: the block program interpreted (what `kinegen
//                analyze` runs, with the generated solve_step's bits), from the previous solution
//   in-proc dense BasicSolver<ProgramSystem>: the dense Newton on the interpreted programs
//                (`kinegen analyze --solver dense`)
//   generic      a hand-written joint-library solver (bench/generic_solver.hpp from the
//                work-precision benchmark), when that header is present
//
// The best of several repetitions is reported; ratios come from the same run. Also printed:
// the largest difference of the block solver's q, qd, qdd from the dense solver's (solved to
// 1e-14) over the grid. Prints a table; not a test.
#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <kinegen/solver.hpp>
#include <string>

#include "best_of_chunks.hpp"
#include "four_bar.hpp"
#include "kinegen/codegen/analysis/block_interpreter.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "offset_slider_crank.hpp"
#include "quick_return.hpp"
#include "slider_crank.hpp"

#if __has_include("generic_from_mechanism.hpp")
#include "generic_from_mechanism.hpp"
#define KINEGEN_BENCH_GENERIC 1
#endif

namespace {

// Timed in short chunks that continue one trajectory; the best chunk counts, so that other
// processes on a shared machine disturb the figures as little as possible.
constexpr int kChunk = 1000;
constexpr int kChunks = 60;
constexpr int kSteps = kChunk * kChunks;
constexpr double kDt = 2 * M_PI / 3600;  // 0.1 degree of crank per step

double g_checksum = 0;

// Best time per step over the chunks (best_of_chunks.hpp).
template <class Chunk>
double best_ns(Chunk&& chunk) {
  return kinegen::bench::best_ns(kChunks, kChunk, chunk);
}

// position / velocity / acceleration calls, Newton from the previous solution.
template <class SolverT, class Vector>
double calls_ns(SolverT& solver, const Vector& q0) {
  Vector q = q0, qd = q0, qdd = q0;
  const double ns = best_ns([&](int k0) {
    for (int k = k0; k < k0 + kChunk; ++k) {
      const double t = k * kDt;
      if (!solver.position(q, t)) return false;
      solver.velocity(q, t, qd);
      solver.acceleration(q, qd, t, qdd);
    }
    return true;
  });
  g_checksum += q.sum() + qdd.sum();
  return ns;
}

// The in-process block program's full step, Newton from the previous solution.
double interpreter_ns(kinegen::codegen::BlockInterpreter& blocks, const Eigen::VectorXd& q0) {
  Eigen::VectorXd q = q0, qd = Eigen::VectorXd::Zero(q0.size()), qdd = qd;
  const kinegen::codegen::BlockInterpreter::Options o;
  const double ns = best_ns([&](int k0) {
    for (int k = k0; k < k0 + kChunk; ++k)
      if (blocks.solve_step(q.data(), k * kDt, qd.data(), qdd.data(), o).status != 0) return false;
    return true;
  });
  g_checksum += q.sum() + qdd.sum();
  return ns;
}

template <class SolverT, class Vector>
double step_ns(SolverT& solver, const Vector& q0) {
  Vector q = q0, qd = Vector::Zero(), qdd = Vector::Zero();
  solver.reset();
  const double ns = best_ns([&](int k0) {
    for (int k = k0; k < k0 + kChunk; ++k)
      if (!solver.step(k * kDt, q, qd, qdd)) return false;
    return true;
  });
  g_checksum += q.sum() + qdd.sum();
  return ns;
}

// Largest difference of the predictor-driven block solver from a tightly solved dense one.
template <class Model>
double max_difference(kinegen::SolverOptions block_options) {
  kinegen::SolverOptions tight;
  tight.tolerance = 1e-14;
  kinegen::DenseSolver<Model> dense({}, tight);
  kinegen::Solver<Model> block({}, block_options);
  auto q = block.initial_estimate(), qd = q, qdd = q;
  auto dq = q, dqd = q, dqdd = q;
  qd.setZero();
  qdd.setZero();
  double worst = 0;
  for (int k = 0; k < kSteps; ++k) {
    const double t = k * kDt;
    if (!block.step(t, q, qd, qdd)) return NAN;
    dq = q;
    if (!dense.position(dq, t)) return NAN;
    dense.velocity(dq, t, dqd);
    dense.acceleration(dq, dqd, t, dqdd);
    worst =
        std::max({worst, (q - dq).cwiseAbs().maxCoeff(), (qd - dqd).cwiseAbs().maxCoeff(),
                  (qdd - dqdd).cwiseAbs().maxCoeff() / std::max(1.0, dqdd.cwiseAbs().maxCoeff())});
  }
  return worst;
}

template <class Model>
void run(const char* name) {
  kinegen::Solver<Model> block;
  const auto q0 = block.initial_estimate();
  const double t_step = step_ns(block, q0);
  const double t_calls = calls_ns(block, q0);
  kinegen::SolverOptions fixed;
  fixed.fixed_iterations = 1;
  kinegen::Solver<Model> block_fixed({}, fixed);
  const double t_fixed = step_ns(block_fixed, q0);
  kinegen::DenseSolver<Model> dense;
  const double t_dense = calls_ns(dense, q0);

  const auto model = kinegen::codegen::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                                "/examples/" + name + ".yaml");
  kinegen::BasicSolver<kinegen::codegen::ProgramSystem> inprocess{
      kinegen::codegen::ProgramSystem(*model)};
  const Eigen::VectorXd q0_dynamic = model->q0();
  const double t_inprocess_dense = calls_ns(inprocess, q0_dynamic);
  kinegen::codegen::BlockInterpreter blocks(*model);
  const double t_inprocess = interpreter_ns(blocks, q0_dynamic);
  double t_generic = NAN;
#ifdef KINEGEN_BENCH_GENERIC
  std::string why;
  if (auto data = kinegen::generic::from_compiled_model(*model, why)) {
    kinegen::BasicSolver<kinegen::generic::GenericSystem> generic{
        kinegen::generic::GenericSystem(*data)};
    t_generic = calls_ns(generic, q0_dynamic);
  }
#endif
  const double diff = max_difference<Model>({});
  const double diff_fixed = max_difference<Model>(fixed);
  std::printf(
      "%-20s %3d %2d/%-2d %9.0f %7.0f %7.0f %7.0f %10.0f %10.0f %8.0f %7.1fx %7.1fx %7.1fx %9.1e "
      "%9.1e\n",
      name, Model::nq, Model::num_blocks - Model::num_explicit_blocks, Model::num_blocks, t_step,
      t_calls, t_fixed, t_dense, t_inprocess, t_inprocess_dense, t_generic, t_dense / t_step, t_inprocess / t_step,
      t_generic / t_step, diff, diff_fixed);
}

}  // namespace

int main() {
  std::printf(
      "ns per full step (position + velocity + acceleration), best of %d chunks of %d steps of 0.1 "
      "deg\n",
      kChunks, kChunk);
#ifndef KINEGEN_BENCH_GENERIC
  std::printf("(generic joint-library solver not built: bench/generic_solver.hpp is absent)\n");
#endif
  std::printf("%-20s %3s %5s %9s %7s %7s %7s %10s %10s %8s %8s %8s %8s %9s %9s\n", "model", "nq",
              "newt", "block+pred", "block", "fixed-1", "dense", "in-process", "in-p dense",
              "generic", "dense/",
              "inproc/", "generic/", "max diff", "diff fix1");
  run<kinegen::models::slider_crank>("slider_crank");
  run<kinegen::models::offset_slider_crank>("offset_slider_crank");
  run<kinegen::models::four_bar>("four_bar");
  run<kinegen::models::quick_return>("quick_return");
  std::printf(
      "(newt = Newton blocks / all blocks; ratios against block+pred; max diff: largest\n"
      " |q|, |qd| and relative |qdd| difference from the dense solver at tolerance 1e-14;\n"
      " checksum %g)\n",
      g_checksum);
  return 0;
}
