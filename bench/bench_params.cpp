// Run-time Params against parameters folded into constants (`kinegen generate --fold-params`):
// ns per full analysis step (position by Newton from the previous solution, then velocity and
// acceleration) through Solver<Model>, for each example. The two variants run in this one
// process on the same time grid, in alternating repetitions, timed in thread CPU time; best
// of several repetitions. Prints a table; not a test.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <kinegen/solver.hpp>

#include "four_bar.hpp"
#include "four_bar_folded.hpp"
#include "offset_slider_crank.hpp"
#include "offset_slider_crank_folded.hpp"
#include "quick_return.hpp"
#include "quick_return_folded.hpp"
#include "slider_crank.hpp"
#include "slider_crank_folded.hpp"

namespace {

// Thread CPU time: on a shared machine, time spent preempted does not count against either.
double cpu_ns() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e9 + ts.tv_nsec;
}

constexpr int kSteps = 100000;
constexpr int kRepetitions = 15;
constexpr double kDt = 2 * M_PI / 3600;  // 0.1 degree of crank per step

template <class Model>
double ns_per_step(double& checksum, int repetitions) {
  kinegen::Solver<Model> solver;
  using Vector = typename kinegen::Solver<Model>::Vector;
  Vector qd = Vector::Zero(), qdd = Vector::Zero();
  double best = 1e300;
  for (int rep = 0; rep < repetitions; ++rep) {
    Vector q = solver.initial_estimate();
    const double start = cpu_ns();
    for (int k = 0; k < kSteps; ++k) {
      const double t = k * kDt;
      if (!solver.position(q, t)) return NAN;
      solver.velocity(q, t, qd);
      solver.acceleration(q, qd, t, qdd);
    }
    const double stop = cpu_ns();
    best = std::min(best, (stop - start) / kSteps);
    checksum += q.sum() + qdd.sum();
  }
  return best;
}

// The generated functions alone, where folding acts: phi, phi_q, nu and gamma once each.
template <class Model>
double ns_per_evaluation(double& checksum, int repetitions) {
  typename Model::Params params;
  // As in a program that sets them at run time: the compiler may not assume the defaults.
  asm volatile("" : : "r"(&params) : "memory");
  std::array<double, Model::nq> q = Model::q0, qd;
  qd.fill(0.5);
  double out[Model::nc], jac[Model::jac_nnz > 0 ? Model::jac_nnz : 1];
  double best = 1e300;
  for (int rep = 0; rep < repetitions; ++rep) {
    const double start = cpu_ns();
    for (int k = 0; k < kSteps; ++k) {
      const double t = k * kDt;
      q[2] = t;  // keep the compiler from hoisting the work out of the loop
      // Every output is read, so none of the work is dead.
      Model::phi(q.data(), t, params, out);
      for (double v : out) checksum += v;
      Model::phi_q(q.data(), t, params, jac);
      for (double v : jac) checksum += v;
      Model::nu(q.data(), t, params, out);
      for (double v : out) checksum += v;
      Model::gamma(q.data(), qd.data(), t, params, out);
      for (double v : out) checksum += v;
    }
    const double stop = cpu_ns();
    best = std::min(best, (stop - start) / kSteps);
  }
  return best;
}

template <class Plain, class Folded>
void run_functions(const char* name, double& checksum) {
  // Alternating repetitions, so that a change in machine load hits both.
  double plain = 1e300, folded = 1e300;
  for (int rep = 0; rep < kRepetitions; ++rep) {
    plain = std::min(plain, ns_per_evaluation<Plain>(checksum, 1));
    folded = std::min(folded, ns_per_evaluation<Folded>(checksum, 1));
  }
  std::printf("%-22s %4d %12.1f %12.1f %8.2fx\n", name, Plain::nq, plain, folded, plain / folded);
}

template <class Plain, class Folded>
void run(const char* name, double& checksum) {
  // Alternating repetitions, so that a change in machine load hits both.
  double plain = 1e300, folded = 1e300;
  for (int rep = 0; rep < kRepetitions; ++rep) {
    plain = std::min(plain, ns_per_step<Plain>(checksum, 1));
    folded = std::min(folded, ns_per_step<Folded>(checksum, 1));
  }
  std::printf("%-22s %4d %12.0f %12.0f %8.2fx\n", name, Plain::nq, plain, folded, plain / folded);
}

}  // namespace

int main() {
  using namespace kinegen::models;
  std::printf("ns per full step (position + velocity + acceleration), best of %d x %d steps\n",
              kRepetitions, kSteps);
  std::printf("%-22s %4s %12s %12s %9s\n", "model", "nq", "Params", "folded", "speed-up");
  double checksum = 0;
  run<slider_crank, slider_crank_folded>("slider_crank", checksum);
  run<offset_slider_crank, offset_slider_crank_folded>("offset_slider_crank", checksum);
  run<four_bar, four_bar_folded>("four_bar", checksum);
  run<quick_return, quick_return_folded>("quick_return", checksum);
  std::printf("\nns per evaluation of phi, phi_q, nu and gamma, best of %d x %d\n", kRepetitions,
              kSteps);
  std::printf("%-22s %4s %12s %12s %9s\n", "model", "nq", "Params", "folded", "speed-up");
  run_functions<slider_crank, slider_crank_folded>("slider_crank", checksum);
  run_functions<offset_slider_crank, offset_slider_crank_folded>("offset_slider_crank", checksum);
  run_functions<four_bar, four_bar_folded>("four_bar", checksum);
  run_functions<quick_return, quick_return_folded>("quick_return", checksum);
  std::printf("(checksum %g)\n", checksum);
  return 0;
}
