// The generated dynamics() (docs/format.md: Generated code and the runtime) against the command
// line's ReducedDynamics (`kinegen simulate`, analysis/dynamics.cpp) on the dynamics examples:
// the same block program from the same start gives the same q bit for bit, and zdd too or
// within an ulp (the command line solves B = dq/dz on one dense LU of Phi_q, the header through
// its blocks: docs/embedding.md); B against the complex step of the header's own position solve
// (z complex); a free distance item's B is dq/dz of the distance, not of its square; float
// against double.
#include <algorithm>
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <cstdio>
#include <string>

#include "andrews.hpp"
#include "cam_liftoff.hpp"
#include "cart_pole.hpp"
#include "double_cart_pole.hpp"
#include "driven_pendulum.hpp"
#include "four_bar_damped.hpp"
#include "four_bar_spring.hpp"
#include "four_bar_swing.hpp"
#include "kinegen/codegen/analysis/dynamics.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/linearize.hpp"
#include "n_four_bar_4.hpp"
#include "n_four_bar_5.hpp"
#include "pendulum.hpp"
#include "press_flywheel.hpp"
#include "slide_distance.hpp"

namespace {

namespace km = kinegen::models;
namespace kc = kinegen::codegen;

struct Cli {
  std::unique_ptr<kc::CompiledModel> model;
  kc::ForceModel forces;
  std::unique_ptr<kc::ReducedDynamics> dynamics;
  explicit Cli(const std::string& path) {
    kc::BuildOptions build;
    build.free_as_state = true;
    model = kc::CompiledModel::from_file(path, {}, build);
    forces = kc::derive_forces(*model);
    dynamics = std::make_unique<kc::ReducedDynamics>(*model, forces, 0.0);
  }
};

std::string example(const char* name) {
  return std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/" + name + ".yaml";
}

// A dynamics mechanism of the tests' own (tests/dynamics/).
std::string test_mechanism(const char* name) {
  return std::string(KINEGEN_SOURCE_DIR) + "/tests/dynamics/" + name + ".yaml";
}

// |a - b| in units of the last place of the larger of |a| and the largest |zdd| (scale).
double ulps(double a, double b, double scale) {
  const double size = std::max({std::abs(a), std::abs(b), scale});
  return std::abs(a - b) / (std::numeric_limits<double>::epsilon() * size);
}

// The state a little off the initial one: z + dz, zd + dzd at t.
struct Offset {
  double t, dz, dzd;
};

// The command line's two evaluations at the state, the first from its initial state, the
// second from the first's solution, and the header's from the same starts (Newton's, as
// ReducedDynamics predicts them: adding zeros can turn a -0 into +0) with a fresh work space.
// The sin/cos cache: the command line's anchors from its assembly are left behind when every
// moving angle moves by more than the rotation limit (1/32 rad), and then both caches hold the
// same anchors. Checks q bit for bit; returns the largest zdd difference in ulps of the scale.
template <class M>
double compare_with_cli(const std::string& path, Offset at, bool same_anchors = true) {
  Cli cli(path);
  const kc::MotionState& s0 = cli.dynamics->initial();
  const Eigen::VectorXd z = s0.z.array() + at.dz, zd = s0.zd.array() + at.dzd;
  const auto predicted = [&](const kc::MotionState& from) {
    const Eigen::MatrixXd b = cli.dynamics->b();
    const Eigen::VectorXd rheonomic = from.qd - b * from.zd;
    Eigen::VectorXd start = from.q;
    start += b * (z - from.z) + (at.t - from.t) * rheonomic;
    return start;
  };
  typename M::template DynamicsWork<double> w;
  double worst = 0;
  kc::MotionState last = s0;
  for (int call = 0; call < 2; ++call) {
    const Eigen::VectorXd start = predicted(last);
    kc::MotionState out;
    REQUIRE(cli.dynamics->evaluate(at.t, z.data(), zd.data(), out));
    for (int k = 0; k < M::nq; ++k) w.q[k] = start[k];
    double zdd[M::nf];
    const auto r = M::dynamics(z.data(), zd.data(), at.t, typename M::Params{}, zdd,
                               typename M::BlockOptions{}, w);
    REQUIRE(r.status == 0);
    for (int k = 0; k < M::nq; ++k) {
      INFO("call " << call << ", q[" << k << "]");
      if (same_anchors) {
        CHECK(w.q[k] == out.q[k]);  // the same Newton from the same start
      } else {                      // sin and cos from other anchors: the last bits
        CHECK(w.q[k] == Approx(out.q[k]).epsilon(4e-15).margin(4e-15));
      }
      CHECK(w.qd[k] == Approx(out.qd[k]).margin(1e-13));
    }
    // B: the command line's from one dense LU of Phi_q, the header's through its blocks.
    double b_diff = 0;
    for (int k = 0; k < M::nf; ++k)
      for (int i = 0; i < M::nq; ++i)
        b_diff = std::max(b_diff, std::abs(w.b[k * M::nq + i] - cli.dynamics->b()(i, k)));
    const double scale = out.zdd.cwiseAbs().maxCoeff();
    for (int k = 0; k < M::nf; ++k) worst = std::max(worst, ulps(zdd[k], out.zdd[k], scale));
    std::printf("  call %d: B within %.2e\n", call, b_diff);
    last = out;
  }
  return worst;
}

// B = dq/dz of the header against the complex step of its own position solve: q(z + i h e_k)
// has imaginary part h B e_k (h = 1e-30: no cancellation, no truncation).
template <class M>
double b_against_complex_step(const double* z, const double* zd, double t) {
  using C = std::complex<double>;
  typename M::template DynamicsWork<double> w;
  double zdd[M::nf];
  REQUIRE(M::dynamics(z, zd, t, typename M::Params{}, zdd, typename M::BlockOptions{}, w).status ==
          0);
  double worst = 0, scale = 0;
  for (double v : w.b) scale = std::max(scale, std::abs(v));
  for (int k = 0; k < M::nf; ++k) {
    C zc[M::nf], zdc[M::nf], zddc[M::nf];
    for (int i = 0; i < M::nf; ++i) {
      zc[i] = C(z[i], i == k ? 1e-30 : 0.0);
      zdc[i] = zd[i];
    }
    typename M::template DynamicsWork<C> wc;
    for (int i = 0; i < M::nq; ++i) wc.q[i] = w.q[i];
    REQUIRE(M::dynamics(zc, zdc, C(t), typename M::Params{}, zddc, typename M::BlockOptions{}, wc)
                .status == 0);
    for (int i = 0; i < M::nq; ++i)
      worst = std::max(worst, std::abs(wc.q[i].imag() / 1e-30 - w.b[k * M::nq + i]) / scale);
    for (int i = 0; i < M::nf; ++i)  // the real part is the real dynamics
      CHECK(zddc[i].real() == Approx(zdd[i]).epsilon(1e-13).margin(1e-13));
  }
  return worst;
}

template <class M>
void check_example(const char* name, Offset at, bool same_anchors = true) {
  const double d = compare_with_cli<M>(example(name), at, same_anchors);
  std::printf("generated dynamics() against ReducedDynamics, %s: zdd within %.1f ulps\n", name, d);
  CHECK(d <= (same_anchors ? 1 : 16));
  Cli cli(example(name));
  const kc::MotionState& s0 = cli.dynamics->initial();
  const Eigen::VectorXd z = s0.z.array() + at.dz, zd = s0.zd.array() + at.dzd;
  const double b = b_against_complex_step<M>(z.data(), zd.data(), at.t);
  INFO(name << ": B against the complex step " << b);
  CHECK(b < 1e-13);
}

}  // namespace

TEST_CASE("generated dynamics() agrees with the command line's ReducedDynamics",
          "[generated_dynamics]") {
  check_example<km::pendulum>("pendulum", {0.0, 0.0, 0.0});
  check_example<km::pendulum>("pendulum", {0.3, -0.7, 2.5});
  check_example<km::press_flywheel>("press_flywheel", {0.02, 0.2, 1.0});
  check_example<km::four_bar_damped>("four_bar_damped", {0.0, 0.2, -0.4});
  check_example<km::cam_liftoff>("cam_liftoff", {0.01, 0.2, 0.5});
  check_example<km::cart_pole>("cart_pole", {0.0, 0.2, 0.2});
  check_example<km::four_bar_spring>("four_bar_spring", {0.0, -0.6, 0.3});
  // A prescribed driver beside the free item, a torn seven-body loop, the N-four-bar.
  check_example<km::driven_pendulum>("driven_pendulum", {0.01, 0.2, 0.5});
  check_example<km::four_bar_swing>("four_bar_swing", {0.0, 0.2, 1.0});
  // Some of Andrews' links swing less than 1/32 rad: the command line rotates their sin and
  // cos from the anchors of its assembly, which a fresh work space does not have.
  check_example<km::andrews>("andrews", {0.001, 0.6, 100.0}, false);
  check_example<km::n_four_bar_4>("n_four_bar_4", {0.0, 0.2, 1.0});
}

TEST_CASE("a free distance item's B is dq/dz of the distance (|d|^2 - z^2 written squared)",
          "[generated_dynamics]") {
  using M = km::slide_distance;
  const double z[] = {2.5}, zd[] = {0.5};
  typename M::DynamicsWork<double> w;
  double zdd[1];
  REQUIRE(M::dynamics(z, zd, 0.0, M::Params{}, zdd, M::BlockOptions{}, w).status == 0);
  CHECK(w.b[0] == Approx(1).epsilon(1e-15));  // dx/ds = 1, not 1 / (2 s)
  CHECK(w.qd[0] == Approx(0.5).epsilon(1e-15));
  CHECK(zdd[0] == Approx(1.5).epsilon(1e-15));  // F / m
  CHECK(b_against_complex_step<M>(z, zd, 0.0) < 1e-15);
  const double d = compare_with_cli<M>(test_mechanism("slide_distance"), {0.0, 0.5, 0.0});
  CHECK(d <= 2);
}

namespace {

// The one run-time input of these examples: the cart-pole's push_x.
template <class M>
void set_input(typename M::Params& p, double u) {
  if constexpr (M::num_inputs > 0) p.push_x = u;
}

// The header's Jacobians against `kinegen linearize` (Linearizer: the same tangent program and
// kernel; B from its dense LU) at the state a little off the initial one, from the same q; and
// against the complex step of the header's own dynamics() in std::complex<double> (z and zd)
// and central differences (u, a Params member). Returns the largest differences relative to
// the Jacobians' scale: {against the command line, against the complex step}.
template <class M>
std::pair<double, double> check_jacobians_of(const std::string& file, const char* name, Offset at,
                                             double u = 0) {
  Cli cli(file);
  kc::Linearizer lin(*cli.model, cli.forces, 0.0);
  kc::OperatingPoint op = lin.initial();
  op.t = at.t;
  op.z.array() += at.dz;
  op.zd.array() += at.dzd;
  if (op.u.size() > 0) op.u[0] = u;
  const kc::LinearModel first = kc::linearize(lin, op);
  const kc::LinearModel l = kc::linearize(lin, op);  // from the first's solution
  constexpr int nf = M::nf, nu = M::num_inputs;
  typename M::Params p{};
  set_input<M>(p, u);
  typename M::template DynamicsWork<double> w;
  for (int k = 0; k < M::nq; ++k) w.q[k] = first.state.q[k];
  double zdd[nf] = {}, dz[nf * nf] = {}, dzd[nf * nf] = {}, du[nf * (nu > 0 ? nu : 1)] = {};
  REQUIRE(M::dynamics_jacobians(op.z.data(), op.zd.data(), op.t, p, zdd, dz, dzd,
                                nu > 0 ? du : nullptr, typename M::BlockOptions{}, w)
              .status == 0);
  Eigen::MatrixXd mine(nf, 2 * nf + nu), cli_j(nf, 2 * nf + nu);
  for (int j = 0; j < nf; ++j)
    for (int i = 0; i < nf; ++i) {
      mine(i, j) = dz[j * nf + i];
      mine(i, nf + j) = dzd[j * nf + i];
    }
  for (int j = 0; j < nu; ++j)
    for (int i = 0; i < nf; ++i) mine(i, 2 * nf + j) = du[j * nf + i];
  cli_j << l.a.bottomRows(nf), l.b.bottomRows(nf);
  const double scale = std::max(cli_j.cwiseAbs().maxCoeff(), l.state.zdd.cwiseAbs().maxCoeff());
  const double vs_cli = (mine - cli_j).cwiseAbs().maxCoeff() / scale;
  // The complex step along z_j and zd_j.
  using C = std::complex<double>;
  const double h = 1e-30;
  Eigen::MatrixXd step(nf, 2 * nf + nu);
  for (int j = 0; j < 2 * nf; ++j) {
    C z[nf], zd[nf], zddc[nf];
    for (int i = 0; i < nf; ++i) {
      z[i] = C(op.z[i], j == i ? h : 0.0);
      zd[i] = C(op.zd[i], j == nf + i ? h : 0.0);
    }
    typename M::template DynamicsWork<C> wc;
    for (int k = 0; k < M::nq; ++k) wc.q[k] = w.q[k];
    REQUIRE(M::dynamics(z, zd, C(op.t), p, zddc, typename M::BlockOptions{}, wc).status == 0);
    for (int i = 0; i < nf; ++i) step(i, j) = zddc[i].imag() / h;
  }
  // Central differences along u (a Params member, double only).
  for (int j = 0; j < nu; ++j) {
    const double du_step = 1e-5;
    double plus[nf], minus[nf];
    typename M::Params pp = p;
    set_input<M>(pp, u + du_step);
    typename M::template DynamicsWork<double> wp = w;
    REQUIRE(M::dynamics(op.z.data(), op.zd.data(), op.t, pp, plus, typename M::BlockOptions{}, wp)
                .status == 0);
    set_input<M>(pp, u - du_step);
    REQUIRE(M::dynamics(op.z.data(), op.zd.data(), op.t, pp, minus, typename M::BlockOptions{}, wp)
                .status == 0);
    for (int i = 0; i < nf; ++i) {
      step(i, 2 * nf + j) = (plus[i] - minus[i]) / (2 * du_step);
      CHECK(std::abs(step(i, 2 * nf + j) - mine(i, 2 * nf + j)) < 1e-8 * scale);
    }
  }
  const double vs_step = (mine - step).leftCols(2 * nf).cwiseAbs().maxCoeff() / scale;
  std::printf(
      "generated dynamics_jacobians, %s: %.2e from `kinegen linearize`, %.2e from the "
      "complex step (relative to %.3g)\n",
      name, vs_cli, vs_step, scale);
  return {vs_cli, vs_step};
}

template <class M>
std::pair<double, double> check_jacobians(const char* name, Offset at, double u = 0) {
  return check_jacobians_of<M>(example(name), name, at, u);
}

}  // namespace

TEST_CASE("generated dynamics_jacobians against `kinegen linearize` and the complex step",
          "[generated_dynamics]") {
  for (const Offset at : {Offset{0.0, 0.0, 0.0}, Offset{0.1, 0.2, -0.5}}) {
    const auto cart = check_jacobians<km::cart_pole>("cart_pole", at, 0.7);
    CHECK(cart.first < 1e-14);
    CHECK(cart.second < 1e-12);
    const auto spring = check_jacobians<km::four_bar_spring>("four_bar_spring", at);
    CHECK(spring.first < 1e-14);
    CHECK(spring.second < 1e-12);
  }
  const auto damped = check_jacobians<km::four_bar_damped>("four_bar_damped", {0.0, 0.3, 1.0});
  CHECK(damped.first < 1e-14);
  CHECK(damped.second < 1e-12);
  const auto press = check_jacobians<km::press_flywheel>("press_flywheel", {0.02, 0.05, 1.0});
  CHECK(press.first < 1e-14);
  CHECK(press.second < 1e-12);
  const auto pair =
      check_jacobians<km::double_cart_pole>("double_cart_pole", {0.0, 0.1, -0.4}, -1.5);
  CHECK(pair.first < 1e-14);
  CHECK(pair.second < 1e-12);
  // A model whose work space is too large for the stack (JacobianWork's arrays instead: it has
  // no sin/cos cache of its own, so its size is the arrays').
  static_assert(sizeof(km::n_four_bar_5::JacobianWork<double>) > KINEGEN_STACK_WORK_BYTES);
  const auto chain = check_jacobians_of<km::n_four_bar_5>(test_mechanism("n_four_bar_5"),
                                                          "n_four_bar_5", {0.0, 0.2, 1.0});
  CHECK(chain.first < 1e-14);
  CHECK(chain.second < 1e-12);
}

namespace {

// dynamics() in float against double at the state a little off the initial one: the largest
// zdd difference over max(1, the largest |zdd|).
template <class M>
double float_against_double(const char* name, Offset at) {
  Cli cli(example(name));
  const kc::MotionState& s0 = cli.dynamics->initial();
  double z[M::nf], zd[M::nf], zdd[M::nf];
  float zf[M::nf], zdf[M::nf], zddf[M::nf] = {};
  for (int k = 0; k < M::nf; ++k) {
    z[k] = s0.z[k] + at.dz;
    zd[k] = s0.zd[k] + at.dzd;
    zf[k] = static_cast<float>(z[k]);
    zdf[k] = static_cast<float>(zd[k]);
  }
  typename M::template DynamicsWork<double> w;
  typename M::template DynamicsWork<float> wf;
  for (int k = 0; k < M::nq; ++k) {  // the assembled start, as a simulation's
    w.q[k] = s0.q[k];
    wf.q[k] = static_cast<float>(s0.q[k]);
  }
  REQUIRE(
      M::dynamics(z, zd, at.t, typename M::Params{}, zdd, typename M::BlockOptions{}, w).status ==
      0);
  // float's own tolerances (BasicBlockOptions<float>: 3.1e-5 on the step, 2.4e-4 residual).
  REQUIRE(M::dynamics(zf, zdf, static_cast<float>(at.t), typename M::Params{}, zddf,
                      typename M::template BasicBlockOptions<float>{}, wf)
              .status == 0);
  double scale = 1, worst = 0;
  for (int k = 0; k < M::nf; ++k) scale = std::max(scale, std::abs(zdd[k]));
  for (int k = 0; k < M::nf; ++k) worst = std::max(worst, std::abs(zddf[k] - zdd[k]) / scale);
  std::printf("generated dynamics() in float, %s: %.2e from double (relative to %.3g)\n", name,
              worst, scale);
  return worst;
}

}  // namespace

TEST_CASE("generated dynamics() in float is within 1e-5 of double", "[generated_dynamics]") {
  CHECK(float_against_double<km::pendulum>("pendulum", {0.3, -0.7, 2.5}) < 1e-5);
  CHECK(float_against_double<km::press_flywheel>("press_flywheel", {0.02, 0.05, 1.0}) < 1e-5);
  CHECK(float_against_double<km::four_bar_damped>("four_bar_damped", {0.0, 0.1, -0.4}) < 1e-5);
  CHECK(float_against_double<km::cam_liftoff>("cam_liftoff", {0.01, 0.02, 0.5}) < 1e-5);
  CHECK(float_against_double<km::cart_pole>("cart_pole", {0.0, 0.05, 0.2}) < 1e-5);
  CHECK(float_against_double<km::four_bar_spring>("four_bar_spring", {0.0, -0.05, 0.3}) < 1e-5);
}

namespace {

// The cart-pole's Jacobians (A's lower half and B, nf x (2 nf + 1)) at (z, zd, t, p) with w.
using CartJacobians = std::array<double, 2 * 6>;
kinegen::models::cart_pole::BlockReport<double> cart_jacobians(
    const double* z, const double* zd, double t, const km::cart_pole::Params& p,
    const km::cart_pole::BlockOptions& o, km::cart_pole::DynamicsWork<double>& w,
    CartJacobians& out) {
  double zdd[2];
  return km::cart_pole::dynamics_jacobians(z, zd, t, p, zdd, out.data(), out.data() + 4,
                                           out.data() + 8, o, w);
}

double largest_difference(const CartJacobians& a, const CartJacobians& b) {
  double d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

}  // namespace

// dynamics_jacobians takes the solution of a dynamics() just made with the same work space
// and the same arguments (an integrator's or a controller's step evaluates f there first), and
// solves again whenever any argument differs or that call failed: never a stale answer.
TEST_CASE("dynamics_jacobians reuses a dynamics() at the same point, and only there",
          "[generated_dynamics]") {
  using M = km::cart_pole;
  const double z[] = {0.1, 2.9}, zd[] = {0.2, -0.3};
  M::Params p{};
  p.push_x = 0.7;
  const M::BlockOptions o{};
  // The truth at each point: a fresh work space, which reuses nothing.
  const auto fresh = [&](const double* at_z, double t, const M::Params& at_p) {
    M::DynamicsWork<double> w;
    CartJacobians j{};
    REQUIRE(cart_jacobians(at_z, zd, t, at_p, o, w, j).status == 0);
    return j;
  };
  M::DynamicsWork<double> w;
  double zdd[2];
  REQUIRE(M::dynamics(z, zd, 0.0, p, zdd, o, w).status == 0);
  CHECK(w.solved);
  CartJacobians j{};
  const M::BlockReport<double> r = cart_jacobians(z, zd, 0.0, p, o, w, j);
  REQUIRE(r.status == 0);
  CHECK(largest_difference(j, fresh(z, 0.0, p)) == 0);  // the same solve from q0: same bits
  // Each argument changed in turn: the Jacobians are the new point's, not the stored ones.
  M::Params heavier = p;
  heavier.m = 2 * p.m;
  M::Params pushed = p;
  pushed.push_x = -3.0;
  const double moved[] = {0.1, 2.5};
  const CartJacobians at_p = fresh(z, 0.0, heavier);
  REQUIRE(largest_difference(at_p, j) > 1e-3);  // the test can fail
  REQUIRE(M::dynamics(z, zd, 0.0, p, zdd, o, w).status == 0);
  REQUIRE(cart_jacobians(z, zd, 0.0, heavier, o, w, j).status == 0);
  CHECK(largest_difference(j, at_p) < 1e-12);
  REQUIRE(M::dynamics(z, zd, 0.0, p, zdd, o, w).status == 0);
  REQUIRE(cart_jacobians(moved, zd, 0.0, p, o, w, j).status == 0);
  CHECK(largest_difference(j, fresh(moved, 0.0, p)) < 1e-12);
  REQUIRE(M::dynamics(z, zd, 0.0, p, zdd, o, w).status == 0);
  REQUIRE(cart_jacobians(z, zd, 0.0, pushed, o, w, j).status == 0);
  CHECK(largest_difference(j, fresh(z, 0.0, pushed)) < 1e-12);
  // A new start written into the work space (its q, which the caller may set) is a new
  // problem: solved again from there, never the stored B and factors with the new q.
  REQUIRE(M::dynamics(z, zd, 0.0, p, zdd, o, w).status == 0);
  w.q[5] += 0.25;  // the pole's angle
  REQUIRE(cart_jacobians(z, zd, 0.0, p, o, w, j).status == 0);
  CHECK(largest_difference(j, fresh(z, 0.0, p)) < 1e-12);
  // Other options: solved again under them (with min_rcond 2 no block passes, status 2),
  // where the stored solution would have been taken.
  M::BlockOptions strict = o;
  strict.min_rcond = 2.0;
  REQUIRE(M::dynamics(z, zd, 0.0, p, zdd, o, w).status == 0);
  CHECK(cart_jacobians(z, zd, 0.0, p, strict, w, j).status == 2);
  CHECK_FALSE(w.solved);
  // After a failure nothing is reused, even at the failed call's own arguments.
  CHECK(cart_jacobians(z, zd, 0.0, p, strict, w, j).status == 2);
  REQUIRE(cart_jacobians(z, zd, 0.0, p, o, w, j).status == 0);
  CHECK(largest_difference(j, fresh(z, 0.0, p)) < 1e-12);
}

namespace {

// dynamics_jacobians along a motion with one DynamicsWork and one JacobianWork kept from call to
// call (their sin/cos caches rotated from earlier anchors; one step of 0.6 rad, beyond the
// caches' reach), against fresh work spaces from the same q at every point; then after
// JacobianWork::reset. Returns the largest difference relative to the Jacobians' scale.
template <class M>
double kept_against_fresh(double z0, double zd0) {
  static_assert(M::nf == 1);
  const typename M::Params p{};
  const typename M::BlockOptions o{};
  typename M::template DynamicsWork<double> w;
  typename M::template JacobianWork<double> j;
  double worst = 0;
  for (int k = 0; k <= 30; ++k) {
    const double z = z0 + 0.01 * k + (k >= 15 ? 0.6 : 0.0), zd = zd0;
    if (k == 25) j.reset();
    typename M::template DynamicsWork<double> wf;
    for (int c = 0; c < M::nq; ++c) wf.q[c] = w.q[c];
    double zdd, kept[2], fresh[2];
    // A literal nullptr for the outputs not wanted, as a user writes it.
    REQUIRE(M::dynamics_jacobians(&z, &zd, 0.0, p, &zdd, kept, kept + 1, nullptr, o, w, j).status ==
            0);
    REQUIRE(M::dynamics_jacobians(&z, &zd, 0.0, p, &zdd, fresh, fresh + 1, nullptr, o, wf).status ==
            0);
    const double scale = std::max({std::abs(fresh[0]), std::abs(fresh[1]), 1.0});
    for (int i = 0; i < 2; ++i) worst = std::max(worst, std::abs(kept[i] - fresh[i]) / scale);
  }
  return worst;
}

}  // namespace

TEST_CASE("dynamics_jacobians with work spaces kept along a motion: fresh ones' numbers",
          "[generated_dynamics]") {
  // The pendulum's angle is in JacobianWork's cache, the four-bar's in DynamicsWork's.
  const double pendulum = kept_against_fresh<km::pendulum>(-0.7, 2.5);
  const double four_bar = kept_against_fresh<km::four_bar_spring>(4.2, 0.3);
  std::printf("kept work spaces against fresh ones: pendulum %.2e, four_bar_spring %.2e\n",
              pendulum, four_bar);
  CHECK(pendulum < 4e-16);
  CHECK(four_bar < 4e-15);
}
