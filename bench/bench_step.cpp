// Time per full analysis step (position by Newton from the previous solution, then velocity
// and acceleration) for each example: generated code through Solver<Model> against the same
// runtime algorithm on the in-process evaluator (what `kinegen analyze` runs). Both paths run
// in this one process on the same time grid; the best of several repetitions is reported, and
// the ratio comes from the same run. Prints a table; not a test.
#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "four_bar.hpp"
#include "kinegen/codegen/model.hpp"
#include "offset_slider_crank.hpp"
#include "quick_return.hpp"
#include "slider_crank.hpp"
#include <kinegen/solver.hpp>

namespace {

constexpr int kSteps = 100000;
constexpr int kRepetitions = 5;
constexpr double kDt = 2 * M_PI / 3600;  // 0.1 degree of crank per step

template <class SolverT, class Vector>
double ns_per_step(SolverT& solver, Vector q, double& checksum) {
  Vector qd = q, qdd = q;
  qd.setZero();
  qdd.setZero();
  double best = 1e300;
  for (int rep = 0; rep < kRepetitions; ++rep) {
    Vector qs = q;
    const auto start = std::chrono::steady_clock::now();
    for (int k = 0; k < kSteps; ++k) {
      const double t = k * kDt;
      if (!solver.position(qs, t)) return NAN;
      solver.velocity(qs, t, qd);
      solver.acceleration(qs, qd, t, qdd);
    }
    const auto stop = std::chrono::steady_clock::now();
    best = std::min(best, std::chrono::duration<double, std::nano>(stop - start).count() / kSteps);
    checksum += qs.sum() + qdd.sum();
  }
  return best;
}

template <class Model>
void run(const char* name, double& checksum) {
  kinegen::Solver<Model> generated;
  const double t_gen = ns_per_step(generated, generated.initial_estimate(), checksum);

  const auto model = kinegen::codegen::CompiledModel::from_file(
      std::string(KINEGEN_SOURCE_DIR) + "/examples/" + name + ".yaml");
  kinegen::BasicSolver<kinegen::codegen::ProgramSystem> inprocess{
      kinegen::codegen::ProgramSystem(*model)};
  const Eigen::VectorXd q0 = model->q0();
  const double t_eval = ns_per_step(inprocess, q0, checksum);
  std::printf("%-22s %4d %14.0f %14.0f %8.1fx\n", name, Model::nq, t_gen, t_eval, t_eval / t_gen);
}

}  // namespace

int main() {
  std::printf("ns per full step (position + velocity + acceleration), best of %d x %d steps\n",
              kRepetitions, kSteps);
  std::printf("%-22s %4s %14s %14s %9s\n", "model", "nq", "generated", "in-process", "ratio");
  double checksum = 0;
  run<kinegen::models::slider_crank>("slider_crank", checksum);
  run<kinegen::models::offset_slider_crank>("offset_slider_crank", checksum);
  run<kinegen::models::four_bar>("four_bar", checksum);
  run<kinegen::models::quick_return>("quick_return", checksum);
  std::printf("(checksum %g)\n", checksum);
  return 0;
}
