// The embedded solver (kinegen::Solver and the generated block functions) never reports
// success on a wrong answer (issue 13, items 1, 3, 4 and 5), in double and float: float works
// with default options, long runs converge, an exhausted fixed budget is a failure with its
// residual, a zero-filled sin/cos cache is not trusted, and a jump to another assembly branch
// is seen through the determinant signs.
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <kinegen/block_options.hpp>
#include <kinegen/solver.hpp>

#include "drag_link.hpp"
#include "four_bar.hpp"
#include "slider_crank.hpp"

namespace {

constexpr double kTwoPi = 6.283185307179586;

// The kernels, the printed code and the analysis name their statuses by the kernels' numbers;
// kinegen::Status reads them as its own.
using Numbers = kinegen::kernels::ReportKernel;
using kinegen::Status;
static_assert(static_cast<int>(Status::kConverged) == Numbers::_kStatusConverged);
static_assert(static_cast<int>(Status::kMaxIterations) == Numbers::_kStatusMaxIterations);
static_assert(static_cast<int>(Status::kSingular) == Numbers::_kStatusSingular);
static_assert(static_cast<int>(Status::kNonFinite) == Numbers::_kStatusNonFinite);
static_assert(static_cast<int>(Status::kInconsistent) == Numbers::_kStatusInconsistent);
static_assert(static_cast<int>(Status::kBudgetExhausted) == Numbers::_kStatusBudgetExhausted);
static_assert(static_cast<int>(Status::kBranchJump) == Numbers::_kStatusBranchJump);
static_assert(static_cast<int>(Status::kTooFar) == Numbers::_kStatusTooFar);

template <class T>
const char* scalar_name() {
  return sizeof(T) == sizeof(float) ? "float" : "double";
}

// Largest |Phi| at q (an independent check of the answer).
template <class Model, class T>
double max_phi(const typename Model::Params& p, const Eigen::Matrix<T, Model::nq, 1>& q, T t) {
  T phi[Model::nc];
  Model::phi(q.data(), t, p, phi);
  double worst = 0;
  for (T v : phi) worst = std::max(worst, static_cast<double>(std::abs(v)));
  return worst;
}

}  // namespace

TEMPLATE_TEST_CASE("four-bar turn of 361 steps succeeds with default options", "[embedded]", double,
                   float) {
  using M = kinegen::models::four_bar;
  kinegen::Solver<M, TestType> solver;
  auto q = solver.initial_estimate();
  decltype(q) qd, qdd;
  REQUIRE(solver.position(q, TestType(0)));
  int failures = 0;
  double worst_phi = 0;
  for (int i = 0; i <= 360; ++i) {
    const TestType t = TestType(i * kTwoPi / 360);
    failures += !solver.step(t, q, qd, qdd);
    worst_phi = std::max(worst_phi, max_phi<M>(M::Params{}, q, t));
  }
  INFO(scalar_name<TestType>());
  CHECK(failures == 0);
  CHECK(worst_phi <= (sizeof(TestType) == 4 ? 1e-5 : 1e-13));
}

TEMPLATE_TEST_CASE("slider-crank: 200 solves from q0 succeed with default options", "[embedded]",
                   double, float) {
  using M = kinegen::models::slider_crank;
  kinegen::Solver<M, TestType> solver;
  int failures = 0;
  double worst_phi = 0;
  for (int i = 0; i < 200; ++i) {
    auto q = solver.initial_estimate();
    const TestType t = TestType(i * kTwoPi / 200);
    failures += !solver.position(q, t);
    worst_phi = std::max(worst_phi, max_phi<M>(M::Params{}, q, t));
  }
  CHECK(failures == 0);
  CHECK(worst_phi <= (sizeof(TestType) == 4 ? 1e-5 : 1e-13));
}

// A drag-link turns every link fully, so its angles grow with the turns: after 1e6 turns
// (angles about 6e6 rad, an ulp of 9e-10 against the 1e-10 tolerance) every step still
// converges, to the motion of the first turn shifted by whole turns.
TEST_CASE("drag-link after 1e6 turns: every step converges, to the right position", "[embedded]") {
  using M = kinegen::models::drag_link;
  const double turns = 1e6, offset = turns * kTwoPi;
  kinegen::Solver<M> solver, reference;
  auto q = solver.initial_estimate();
  decltype(q) qd, qdd;
  REQUIRE(solver.position(q, 0.0));
  for (int k = 2; k < M::nq; k += 3) q[k] += offset;  // the same position, 1e6 turns on
  auto q_ref = q;
  for (int k = 2; k < M::nq; k += 3) q_ref[k] -= offset;
  int failures = 0;
  double worst = 0;
  for (int i = 0; i <= 360; ++i) {
    const double t = offset + i * kTwoPi / 360;
    failures += !solver.step(t, q, qd, qdd);
    // Reference: the first turn, at the same crank angle (t is exact to its ulp, 9e-10).
    REQUIRE(reference.position(q_ref, t - offset));
    for (int k = 0; k < M::nq; ++k)
      worst = std::max(worst, std::abs(q[k] - (k % 3 == 2 ? offset : 0.0) - q_ref[k]));
  }
  CHECK(failures == 0);
  CHECK(worst <= 1e-7);
}

// b = 0.6: |O4 A| reaches d + a = 4 > b + c = 3.1, so at a crank angle of pi the loop cannot
// close. Three fixed iterations must not be reported as success.
TEMPLATE_TEST_CASE("fixed_iterations on a four-bar that cannot close: budget exhausted",
                   "[embedded]", double, float) {
  using M = kinegen::models::four_bar;
  M::Params p;
  p.b = 0.6;
  kinegen::SolverOptions options;
  options.fixed_iterations = 3;
  kinegen::Solver<M, TestType> solver(p, options);
  auto q = solver.initial_estimate();
  const TestType t = TestType(kTwoPi / 2);
  const kinegen::Result r = solver.position(q, t);
  // A first solve follows the crank from q0 (docs/embedding.md, "First solves and branches")
  // and stops where the loop no longer closes: Newton's budget runs out there.
  CHECK((r.status == kinegen::Status::kBudgetExhausted ||
         r.status == kinegen::Status::kMaxIterations));
  CHECK(max_phi<M>(p, q, t) > 0.1);  // indeed not closed
  // The generated function reports the block and its residual.
  auto q2 = solver.initial_estimate();
  typename M::template BasicBlockOptions<TestType> o;
  o.fixed_iterations = 3;
  const auto report = M::solve_position(q2.data(), t, p, o);
  CHECK(report.status == 5);
  CHECK(report.block == 7);
  CHECK(report.iterations == 3);
  CHECK(report.residual > 0.05);
  // On a mechanism that closes, the same budget converges (and reports a tiny residual).
  auto q3 = solver.initial_estimate();
  const auto ok = M::solve_position(q3.data(), TestType(0.1), M::Params{}, o);
  CHECK(ok.status == 0);
  INFO("residual " << double(ok.residual));
  CHECK(ok.residual <= o.residual_tolerance);
  CHECK(ok.rcond > 0.01);
  CHECK(ok.rcond <= 1);
}

// A cache of zeros where the code expects NaN (or anything not written by the solver): not
// trusted, so the answer is the one without a cache.
TEMPLATE_TEST_CASE("zero-filled trig cache does not give a wrong converged answer", "[embedded]",
                   double, float) {
  using M = kinegen::models::four_bar;
  using T = TestType;
  const M::Params p;
  const typename M::template BasicBlockOptions<T> o;
  for (const T t : {T(0), T(0.01), T(0.02)}) {
    std::array<T, M::nq> q_plain, q_zero, qd, qdd;
    for (int k = 0; k < M::nq; ++k) q_plain[k] = q_zero[k] = T(M::q0[k]);
    REQUIRE(M::solve_step(q_plain.data(), t, p, qd.data(), qdd.data(), o).status == 0);
    std::array<T, M::trig_cache_size> zeros{};
    const auto r = M::solve_step(q_zero.data(), t, p, qd.data(), qdd.data(), o, zeros.data());
    INFO("t = " << t);
    if (r.status == 0)
      for (int k = 0; k < M::nq; ++k) CHECK(q_zero[k] == Approx(q_plain[k]).margin(1e-5));
    // The typed cache starts empty.
    typename M::template TrigCache<T> cache;
    auto q_typed = q_plain;
    REQUIRE(M::solve_step(q_typed.data(), t, p, qd.data(), qdd.data(), o, cache.data()).status ==
            0);
    for (int k = 0; k < M::nq; ++k) CHECK(q_typed[k] == Approx(q_plain[k]).margin(1e-5));
  }
}

// The determinant signs of the Newton blocks: recorded on the first solve, and a solve that
// lands on the other assembly branch (the coupler and the rocker mirrored about the line
// A-O4) fails with status 6 (kBranchJump), naming the block.
TEST_CASE("block determinant signs catch a jump to the other assembly branch", "[embedded]") {
  using M = kinegen::models::four_bar;
  const M::Params p;
  const M::BlockOptions o;
  STATIC_REQUIRE(M::num_blocks == 8);
  std::array<signed char, M::num_blocks> signs{};
  std::array<double, M::nq> q;
  for (int k = 0; k < M::nq; ++k) q[k] = M::q0[k];
  const double t = 0.3;
  REQUIRE(
      M::solve_position(q.data(), t, p, o, static_cast<double*>(nullptr), signs.data()).status ==
      0);
  CHECK(signs[7] != 0);
  auto same = q;
  CHECK(M::solve_position(same.data(), t + 0.01, p, o, static_cast<double*>(nullptr), signs.data())
            .status == 0);
  // The crossed branch: mirror the coupler and rocker directions about A -> O4.
  const double ax = q[3], ay = q[4], theta = std::atan2(-ay, p.d - ax);
  auto crossed = q;
  crossed[5] = 2 * theta - q[5];
  crossed[8] = 2 * theta - q[8];
  const auto r =
      M::solve_position(crossed.data(), t, p, o, static_cast<double*>(nullptr), signs.data());
  CHECK(r.status == static_cast<int>(kinegen::Status::kBranchJump));
  CHECK(r.block == 7);
  // Without signs the crossed branch is a valid solution (and is what it converged to).
  auto free = crossed;
  crossed[5] = 2 * theta - q[5];
  CHECK(M::solve_position(free.data(), t, p, o).status == 0);
  CHECK(std::abs(free[5] - q[5]) > 0.1);
}

namespace {

// The options of a header from before min_rcond, max_halvings and residual_tolerance.
struct OldBlockOptions {
  double tolerance = 0;
  int max_iterations = 0;
  int fixed_iterations = 0;
  double singular_pivot_ratio = 0;
};

kinegen::SolverOptions distinct_options() {
  kinegen::SolverOptions s;
  s.tolerance = 3e-9;
  s.max_iterations = 17;
  s.fixed_iterations = 4;
  s.singular_pivot_ratio = 7e-14;
  s.min_rcond = 5e-11;
  s.max_halvings = 3;
  s.residual_tolerance = 2e-7;
  return s;
}

}  // namespace

TEMPLATE_TEST_CASE("block_options_from carries every option the block options have", "[embedded]",
                   double, float) {
  const kinegen::SolverOptions s = distinct_options();
  using O = kinegen::kernels::ReportKernel::BasicBlockOptions<TestType>;
  const O o = kinegen::block_options_from<O>(s);
  CHECK(o.tolerance == TestType(3e-9));
  CHECK(o.max_iterations == 17);
  CHECK(o.fixed_iterations == 4);
  CHECK(o.singular_pivot_ratio == TestType(7e-14));
  CHECK(o.min_rcond == TestType(5e-11));
  CHECK(o.residual_tolerance == TestType(2e-7));
  // A generated header's own options (the runtime's BlockSolver and Simulator convert to them).
  const auto g = kinegen::block_options_from<kinegen::models::four_bar::BlockOptions>(s);
  CHECK(g.fixed_iterations == 4);
  CHECK(g.min_rcond == 5e-11);
  CHECK(g.residual_tolerance == 2e-7);
  // An older header's: what it has, nothing else.
  const OldBlockOptions old = kinegen::block_options_from<OldBlockOptions>(s);
  CHECK(old.tolerance == 3e-9);
  CHECK(old.max_iterations == 17);
  CHECK(old.fixed_iterations == 4);
  CHECK(old.singular_pivot_ratio == 7e-14);
}
