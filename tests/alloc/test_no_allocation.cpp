// Solver<Model> allocates nothing after construction: the global operator new is replaced by
// a counting one, and a full analysis loop (with the generated solve_sensitivity) must leave
// the count unchanged.
#define CATCH_CONFIG_MAIN
#include <catch2/catch.hpp>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

#include "cart_pole.hpp"
#include "four_bar.hpp"
#include "quick_return.hpp"
#include "slider_crank.hpp"
#include "spatial_slider_crank.hpp"
#include <kinegen/simulator.hpp>
#include <kinegen/solver.hpp>

namespace {
std::atomic<long> g_allocations{0};
}

void* operator new(std::size_t size) {
  ++g_allocations;
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

TEMPLATE_TEST_CASE("Solver allocates nothing after construction", "[runtime][alloc]",
                   kinegen::models::slider_crank, kinegen::models::four_bar,
                   kinegen::models::quick_return) {
  kinegen::Solver<TestType> solver;
  auto q = solver.initial_estimate();
  decltype(q) qd = decltype(q)::Zero(), qdd = decltype(q)::Zero();

  const long before = g_allocations.load();
  int solved = 0;
  for (int k = 0; k <= 1000; ++k) {
    const double t = 2 * M_PI * k / 1000;
    if (!solver.position(q, t)) break;
    if (!solver.velocity(q, t, qd)) break;
    if (!solver.acceleration(q, qd, t, qdd)) break;
    // The generated sensitivity solve (its work space on the stack).
    double dq_dp[TestType::nq * TestType::num_params];
    if (TestType::solve_sensitivity(q.data(), t, typename TestType::Params{}, dq_dp,
                                    typename TestType::BlockOptions{})
            .status != 0)
      break;
    ++solved;
  }
  const long after = g_allocations.load();
  REQUIRE(solved == 1001);
  CHECK(after - before == 0);

  // The counter works: a heap allocation is seen.
  auto* probe = new double(1.0);
  CHECK(g_allocations.load() == after + 1);
  delete probe;
}

// The generated dynamics, its Jacobians and the Simulator's steps in a loop.
TEST_CASE("Simulator and dynamics_jacobians allocate nothing", "[runtime][alloc]") {
  using M = kinegen::models::cart_pole;
  kinegen::SimulatorOptions o;
  kinegen::Simulator<M> rk4(M::Params{}, o);
  o.integrator = kinegen::Integrator::kImplicit;
  kinegen::Simulator<M> implicit(M::Params{}, o);
  const double z[] = {0, 1.5}, zd[] = {0, 0};
  REQUIRE(rk4.reset(0, z, zd));
  REQUIRE(implicit.reset(0, z, zd));
  M::DynamicsWork<double> w;
  const long before = g_allocations.load();
  int steps = 0;
  for (int k = 0; k < 500; ++k) {
    rk4.params().push_x = std::sin(0.01 * k);
    if (!rk4.step(1e-3) || !implicit.step(1e-3)) break;
    double zdd[2], dz[4], dzd[4], du[2];
    if (M::dynamics_jacobians(rk4.z(), rk4.zd(), rk4.time(), rk4.params(), zdd, dz, dzd, du,
                              M::BlockOptions{}, w)
            .status != 0)
      break;
    ++steps;
  }
  CHECK(steps == 500);
  CHECK(g_allocations.load() - before == 0);
}

// A spatial header's first solve (the drivers' continuation from the q0 pose, on the stack) and
// its steps with the branch checks.
TEST_CASE("A spatial Solver allocates nothing after construction", "[runtime][alloc]") {
  using M = kinegen::models::spatial_slider_crank;
  kinegen::Solver<M> solver;
  auto q = solver.initial_estimate();
  decltype(q) qd = decltype(q)::Zero(), qdd = decltype(q)::Zero();
  const long before = g_allocations.load();
  int solved = 0;
  for (int k = 0; k <= 200; ++k) {
    if (!solver.step(0.3 + 0.005 * k, q, qd, qdd)) break;
    ++solved;
  }
  CHECK(solved == 201);
  CHECK(g_allocations.load() - before == 0);
}
