// A controller's inner loop: at a fixed rate (1 kHz here), solve the four-bar's position,
// velocity and acceleration for the next tick with a fixed Newton iteration budget, as an
// embedded controller would. Built twice, for float and for double, with -fno-exceptions and
// -fno-rtti (see examples/CMakeLists.txt); the header is generated at build time by
// kinegen_add_model.
//
// Prints the median and worst-case time per call (position + velocity + acceleration) over N
// calls (default 1e6), the worst constraint residual, and the number of heap allocations
// during the loop, counted by a replaced global operator new. Then the same loop on the
// balanced four-bar (examples/forces/four_bar_balanced.yaml, with masses, gravity and a
// spring) adds the feedforward motor torque of each tick (step(), then force_columns() reusing
// the step's factors) and prints its time and the torque's peak over a turn. Exits 1 if
// anything was allocated, a solve failed, or the residual is out of bounds.
//
//   build/examples/controller_double [calls]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <kinegen/solver.hpp>
#include <new>
#include <string_view>
#include <vector>

#include "four_bar.hpp"
#include "four_bar_balanced.hpp"

#ifndef KINEGEN_SCALAR
#define KINEGEN_SCALAR double
#endif

namespace {
long g_allocations = 0;  // single-threaded program
}

// Counting allocation; there are no exceptions to throw, so failure aborts.
void* operator new(std::size_t size) {
  ++g_allocations;
  void* p = std::malloc(size ? size : 1);
  if (!p) std::abort();
  return p;
}
void* operator new[](std::size_t size) { return operator new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace {

// The kinematics as above, then the motor torque the planned motion needs (feedforward):
// Phi_q^T lambda = Q through the blocks, then motor.effort from lambda.
template <class Scalar>
bool feedforward(long calls, std::vector<long>& ns) {
  using Model = kinegen::models::four_bar_balanced;
  using Solver = kinegen::Solver<Model, Scalar>;
  constexpr double kRate = 1000.0;
  constexpr Scalar kDt = Scalar(1 / kRate);
  static_assert(Model::has_forces);
  static_assert(std::string_view(Model::force_column_names[0]) == "motor.effort");
  const Model::Params params{};  // omega: one turn per second
  Solver solver(params);
  typename Solver::Vector q = solver.initial_estimate(), qd, qdd;
  if (!solver.position(q, Scalar(0)) || !solver.velocity(q, Scalar(0), qd) ||
      !solver.acceleration(q, qd, Scalar(0), qdd))
    return false;
  solver.options().fixed_iterations = 2;
  typename Solver::ForceColumns columns;
  double peak = 0;
  long failures = 0;
  const long allocations_before = g_allocations;
  for (long k = 1; k <= calls; ++k) {
    const long tick = k % static_cast<long>(kRate);
    const Scalar t = Scalar(tick) * kDt;
    const auto start = std::chrono::steady_clock::now();
    if (tick == 0) {  // the crank's angle back by a turn: the predictor starts again from here
      q[2] -= Scalar(2 * M_PI);
      solver.reset();
      q += kDt * qd + Scalar(0.5) * kDt * kDt * qdd;
    }
    // step() solves q, qd and qdd and keeps its factors; force_columns at the same t and q
    // reuses them (solve_forces factors nothing again).
    const bool ok = solver.step(t, q, qd, qdd) && solver.force_columns(q, qd, qdd, t, columns);
    const auto stop = std::chrono::steady_clock::now();
    ns[static_cast<std::size_t>(k - 1)] =
        std::chrono::duration_cast<std::chrono::nanoseconds>(stop - start).count();
    failures += !ok;
    if (ok) peak = std::max(peak, double(std::abs(columns[0])));
  }
  const long allocations = g_allocations - allocations_before;
  std::sort(ns.begin(), ns.end());
  std::printf(
      "  balanced four-bar with feedforward torque (step + force_columns, the step's factors "
      "reused):\n    median %ld ns, 99.9%% %ld ns, worst %ld ns; failures: %ld; "
      "peak |motor torque| %.6g N m; heap allocations: %ld\n",
      ns[ns.size() / 2], ns[std::min(ns.size() - 1, ns.size() * 999 / 1000)], ns.back(), failures,
      peak, allocations);
  return allocations == 0 && failures == 0;
}

}  // namespace

int main(int argc, char** argv) {
  using Scalar = KINEGEN_SCALAR;
  using Model = kinegen::models::four_bar;
  using Solver = kinegen::Solver<Model, Scalar>;
  const long calls = argc > 1 ? std::atol(argv[1]) : 1000000;
  if (calls < 1) return 2;
  constexpr bool kFloat = sizeof(Scalar) == sizeof(float);
  constexpr double kRate = 1000.0;  // Hz
  constexpr Scalar kDt = Scalar(1 / kRate);

  // The fixed budget: exactly this many Newton iterations per coupled block and tick, no
  // convergence test, so every tick costs the same. From the Taylor prediction of the last
  // tick's state one iteration reaches rounding; the second one is margin.
  constexpr int kIterations = 2;
  Model::Params params;
  params.omega = 2 * M_PI;  // one crank turn per second
  Solver solver(params);  // default options: tolerances that follow Scalar's precision

  // Everything the loop needs is set up here, before it starts.
  std::vector<long> ns(static_cast<std::size_t>(calls));
  typename Solver::Vector q = solver.initial_estimate(), qd, qdd;
  qd.setZero();
  qdd.setZero();
  // Assembly from the file's rough estimate, outside the loop and its budget.
  if (!solver.position(q, Scalar(0))) return 1;
  // The first prediction needs the state's rates too.
  if (!solver.velocity(q, Scalar(0), qd) || !solver.acceleration(q, qd, Scalar(0), qdd)) return 1;
  solver.options().fixed_iterations = kIterations;
  Scalar phi[Model::nc];
  double worst_residual = 0;
  long failures = 0;

  const long allocations_before = g_allocations;
  for (long k = 1; k <= calls; ++k) {
    // The clock wraps with the crank (one turn per second), and so does the crank's angle:
    // time and angles stay small, which float needs, for any number of calls.
    const long tick = k % static_cast<long>(kRate);
    const Scalar t = Scalar(tick) * kDt;
    const auto start = std::chrono::steady_clock::now();
    if (tick == 0) q[2] -= Scalar(2 * M_PI);
    q += kDt * qd + Scalar(0.5) * kDt * kDt * qdd;  // predict from the last tick
    const kinegen::Result r = solver.position(q, t);
    const bool ok = static_cast<bool>(r);
    const bool ok_v = ok && solver.velocity(q, t, qd);
    const bool ok_a = ok_v && solver.acceleration(q, qd, t, qdd);
    const auto stop = std::chrono::steady_clock::now();
    ns[static_cast<std::size_t>(k - 1)] =
        std::chrono::duration_cast<std::chrono::nanoseconds>(stop - start).count();
    failures += !ok_a;
    Model::phi(q.data(), t, solver.system().params(), phi);
    for (Scalar v : phi) worst_residual = std::max(worst_residual, double(std::abs(v)));
  }
  const long allocations = g_allocations - allocations_before;

  std::sort(ns.begin(), ns.end());
  const long median = ns[ns.size() / 2];
  const long p999 = ns[std::min(ns.size() - 1, ns.size() * 999 / 1000)];
  const long worst = ns.back();
  std::printf("controller_%s: %ld calls at %.0f Hz, %d Newton iterations per block (fixed)\n",
              kFloat ? "float" : "double", calls, kRate, kIterations);
  std::printf(
      "  time per call (position + velocity + acceleration): median %ld ns, "
      "99.9%% %ld ns, worst %ld ns\n",
      median, p999, worst);
  std::printf("  failures: %ld; worst |Phi|: %.3g\n", failures, worst_residual);
  std::printf("  heap allocations in the loop: %ld\n", allocations);
  const double residual_bound = kFloat ? 1e-4 : 1e-9;
  const bool feedforward_ok = feedforward<Scalar>(calls, ns);
  return allocations == 0 && failures == 0 && worst_residual <= residual_bound && feedforward_ok
             ? 0
             : 1;
}
