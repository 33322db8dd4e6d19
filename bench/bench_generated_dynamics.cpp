// The generated dynamics (docs/format.md: Generated code and the runtime) in numbers: the exact
// dynamics_jacobians (after a dynamics() at the point, and alone) against the central
// differences a user would write (2 (2 nf + nu) calls of dynamics()), their times and errors
// (the exact Jacobians' own error against the complex step of dynamics() in
// std::complex<double>, the differences' against the exact), and one dynamics() against one
// Solver::step of the same header with every free item as a driver (the kinematics alone).
// Prints numbers; not a test. Run: build/bench/bench_generated_dynamics
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <kinegen/simulator.hpp>
#include <kinegen/solver.hpp>

#include "best_of_chunks.hpp"
#include "cart_pole.hpp"
#include "double_cart_pole.hpp"
#include "four_bar_damped.hpp"
#include "four_bar_spring.hpp"
#include "pendulum.hpp"
#include "press_flywheel.hpp"

namespace {

namespace km = kinegen::models;
using kinegen::bench::best_ns;
volatile double sink = 0;

template <class M>
void set_free(typename M::Params& p, const double* z, const double* zd);

// Every free item's members as a driver's: value, rate, acceleration 0.
#define KINEGEN_SET_FREE(MODEL, ...)                                                   \
  template <>                                                                          \
  void set_free<km::MODEL>(km::MODEL::Params & p, const double* z, const double* zd) { \
    double* members[][2] = {__VA_ARGS__};                                              \
    for (int k = 0; k < km::MODEL::nf; ++k) {                                          \
      *members[k][0] = z[k];                                                           \
      *members[k][1] = zd[k];                                                          \
    }                                                                                  \
  }
KINEGEN_SET_FREE(pendulum, {&p.theta, &p.theta_v})
KINEGEN_SET_FREE(cart_pole, {&p.x, &p.x_v}, {&p.phi, &p.phi_v})
KINEGEN_SET_FREE(double_cart_pole, {&p.x, &p.x_v}, {&p.phi1, &p.phi1_v}, {&p.phi2, &p.phi2_v})
KINEGEN_SET_FREE(four_bar_spring, {&p.theta, &p.theta_v})
KINEGEN_SET_FREE(four_bar_damped, {&p.theta, &p.theta_v})
KINEGEN_SET_FREE(press_flywheel, {&p.theta, &p.theta_v})
#undef KINEGEN_SET_FREE

template <class M>
void run(const char* name, const double* z0, const double* zd0) {
  constexpr int nf = M::nf, nu = M::num_inputs, cols = 2 * nf + nu;
  const typename M::Params p{};
  const typename M::BlockOptions o{};
  typename M::template DynamicsWork<double> w;
  typename M::template JacobianWork<double> jw;
  double zdd[nf], jac[nf * cols];
  if (M::dynamics(z0, zd0, 0.0, p, zdd, o, w).status != 0) {
    std::printf("%s: dynamics() failed at the start\n", name);
    return;
  }
  const auto exact = [&](double* j) {
    return M::dynamics_jacobians(z0, zd0, 0.0, p, zdd, j, j + nf * nf,
                                 nu > 0 ? j + 2 * nf * nf : nullptr, o, w, jw)
               .status == 0;
  };
  // The differences a user would write along z, zd and u (the Params member): central
  // (2 (2 nf + nu) calls, steps cbrt(eps) max(1, |x|)) or forward (2 nf + nu + 1 calls, steps
  // sqrt(eps) max(1, |x|)), into d.
  double diff[nf * cols], fwd[nf * cols];
  const auto differences = [&](bool central, double* d) {
    const double eps = std::numeric_limits<double>::epsilon();
    const double h0 = central ? std::cbrt(eps) : std::sqrt(eps);
    double x[2 * nf], plus[nf], minus[nf];
    for (int k = 0; k < nf; ++k) x[k] = z0[k], x[nf + k] = zd0[k];
    if (!central && M::dynamics(x, x + nf, 0.0, p, minus, o, w).status != 0) return false;
    const auto column = [&](double h, double* out) {
      for (int i = 0; i < nf; ++i) out[i] = (plus[i] - minus[i]) / (central ? 2 * h : h);
    };
    for (int j = 0; j < 2 * nf; ++j) {
      const double h = h0 * std::max(1.0, std::abs(x[j])), keep = x[j];
      x[j] = keep + h;
      if (M::dynamics(x, x + nf, 0.0, p, plus, o, w).status != 0) return false;
      x[j] = keep - h;
      if (central && M::dynamics(x, x + nf, 0.0, p, minus, o, w).status != 0) return false;
      x[j] = keep;
      column(h, d + j * nf);
    }
    if constexpr (nu > 0) {
      typename M::Params pu = p;
      const double h = h0;
      pu.push_x = p.push_x + h;
      if (M::dynamics(x, x + nf, 0.0, pu, plus, o, w).status != 0) return false;
      pu.push_x = p.push_x - h;
      if (central && M::dynamics(x, x + nf, 0.0, pu, minus, o, w).status != 0) return false;
      column(h, d + 2 * nf * nf);
    }
    return true;
  };
  // After a dynamics() at the point (an integrator's or a controller's step evaluates f
  // there first): the same arguments each time, so dynamics_jacobians takes its solution.
  const double t_exact = best_ns(15, 2000, [&](int) {
    for (int k = 0; k < 2000; ++k)
      if (!exact(jac)) return false;
    sink = sink + jac[0];
    return true;
  });
  // Alone: two points in turn, so that each call solves its dynamics() too.
  double z1[nf], jac1[nf * cols];
  for (int k = 0; k < nf; ++k) z1[k] = z0[k] + 1e-3;
  const double t_alone = best_ns(15, 2000, [&](int) {
    for (int k = 0; k < 1000; ++k) {
      if (!exact(jac)) return false;
      if (M::dynamics_jacobians(z1, zd0, 0.0, p, zdd, jac1, jac1 + nf * nf,
                                nu > 0 ? jac1 + 2 * nf * nf : nullptr, o, w, jw)
              .status != 0)
        return false;
    }
    sink = sink + jac[0] + jac1[0];
    return true;
  });
  const double t_diff = best_ns(15, 2000, [&](int) {
    for (int k = 0; k < 2000; ++k)
      if (!differences(true, diff)) return false;
    sink = sink + diff[0];
    return true;
  });
  const double t_fwd = best_ns(15, 2000, [&](int) {
    for (int k = 0; k < 2000; ++k)
      if (!differences(false, fwd)) return false;
    sink = sink + fwd[0];
    return true;
  });
  exact(jac);
  differences(true, diff);
  differences(false, fwd);
  // The complex step of dynamics() along z and zd: the truth for both.
  using C = std::complex<double>;
  double scale = 0, err_exact = 0, err_diff = 0, err_fwd = 0;
  for (int i = 0; i < nf * cols; ++i) scale = std::max(scale, std::abs(jac[i]));
  for (int j = 0; j < 2 * nf; ++j) {
    C z[nf], zd[nf], out[nf];
    for (int k = 0; k < nf; ++k) {
      z[k] = C(z0[k], j == k ? 1e-30 : 0.0);
      zd[k] = C(zd0[k], j == nf + k ? 1e-30 : 0.0);
    }
    typename M::template DynamicsWork<C> wc;
    for (int k = 0; k < M::nq; ++k) wc.q[k] = w.q[k];
    M::dynamics(z, zd, C(0), p, out, o, wc);
    for (int i = 0; i < nf; ++i) {
      const double truth = out[i].imag() / 1e-30;
      err_exact = std::max(err_exact, std::abs(jac[j * nf + i] - truth) / scale);
      err_diff = std::max(err_diff, std::abs(diff[j * nf + i] - truth) / scale);
      err_fwd = std::max(err_fwd, std::abs(fwd[j * nf + i] - truth) / scale);
    }
  }
  // One dynamics() against one Solver::step on the same motion (z moving by 1e-3 a call).
  kinegen::Solver<M> solver;
  auto q = solver.initial_estimate();
  decltype(q) qd, qdd;
  double z[nf], zd[nf];
  for (int k = 0; k < M::nq; ++k) q[k] = w.q[k];
  // A motion at constant rates from (z0, zd0): t = 1e-5 k.
  const auto along = [&](int k) {
    for (int i = 0; i < nf; ++i) {
      z[i] = z0[i] + zd0[i] * 1e-5 * k;
      zd[i] = zd0[i];
    }
    return 1e-5 * k;
  };
  const double t_step = best_ns(15, 2000, [&](int k0) {
    for (int k = k0; k < k0 + 2000; ++k) {
      const double t = along(k);
      set_free<M>(solver.system().params(), z, zd);
      if (!solver.step(t, q, qd, qdd)) return false;
    }
    sink = sink + qdd[0];
    return true;
  });
  const double t_dyn = best_ns(15, 2000, [&](int k0) {
    for (int k = k0; k < k0 + 2000; ++k) {
      const double t = along(k);
      if (M::dynamics(z, zd, t, p, zdd, o, w).status != 0) return false;
    }
    sink = sink + zdd[0];
    return true;
  });
  std::printf(
      "%-16s %2d %3d %6.0f %6.0f %6.0f %5.1fx %5.1fx %8.1e %8.1e %6.0f %8.1e %5.1fx %5.1fx %5.0f "
      "%5.0f %5.2fx\n",
      name, M::nq, cols, t_exact, t_alone, t_diff, t_diff / t_exact, t_diff / t_alone, err_exact,
      err_diff, t_fwd, err_fwd, t_fwd / t_exact, t_fwd / t_alone, t_dyn, t_step, t_dyn / t_step);
}

}  // namespace

int main() {
  std::printf(
      "ns per call, best of 15 chunks of 2000; exact: dynamics_jacobians after a dynamics() at\n"
      "the point (reused), alone: with its own dynamics(); central: 2 (2 nf + nu) calls of\n"
      "dynamics(), forward: 2 nf + nu + 1; errors against the complex step of dynamics(),\n"
      "relative to the largest Jacobian entry; dyn: one dynamics(), step: one Solver::step\n"
      "                            --- exact ---  -- central differences ---  -- forward "
      "differences --\n"
      "model            nq dir  after  alone   time after alone    error    error   time    error "
      "after alone   dyn  step ratio\n");
  const double pz[] = {-0.7}, pzd[] = {2.5};
  run<km::pendulum>("pendulum", pz, pzd);
  const double cz[] = {0.1, 1.6}, czd[] = {0.2, -0.3};
  run<km::cart_pole>("cart_pole", cz, czd);
  const double sz[] = {4.2}, szd[] = {0.3};
  run<km::four_bar_spring>("four_bar_spring", sz, szd);
  const double dz[] = {-1.5}, dzd[] = {1.0};
  run<km::four_bar_damped>("four_bar_damped", dz, dzd);
  const double fz[] = {0.5}, fzd[] = {10.0};
  run<km::press_flywheel>("press_flywheel", fz, fzd);
  const double wz[] = {0.1, 1.5, 1.7}, wzd[] = {0.2, -0.3, 0.4};
  run<km::double_cart_pole>("double_cart_pole", wz, wzd);
}
