// Integrator kernel: allocation-free fixed-step integrators of x' = f(t, x) for a control loop
// (docs/format.md: Generated code and the runtime): the classical Runge-Kutta step (order 4,
// explicit) and a two-stage, L-stable SDIRK of order 2 for stiff springs, whose stages Newton
// solves with a Jacobian df/dx that the caller gives (a generated header's exact
// dynamics_jacobians) or, the documented fallback, forward differences of f. kinegen::Simulator
// (simulator.hpp) steps a generated model's dynamics() with them. See report.hpp for how kernel
// files are used.
#pragma once

#include <cmath>

#include "kinegen/kernels/lu.hpp"

namespace kinegen::kernels {

struct IntegrateKernel : LuKernel {
  // kinegen-kernel-begin integrate
  // One classical Runge-Kutta step of x' = f(t, x) over h, x (N values) in place. f(t, x, xd)
  // writes x' and returns 0, or a status that ends the step at once with x unchanged.
  template <int N, class T, class F>
  static int _rk4_step(T t, T h, T* x, F&& f) noexcept {
    T k[4][N], y[N];
    const T half = h / T(2);
    if (const int s = f(t, x, k[0])) return s;
    for (int i = 0; i < N; ++i) y[i] = x[i] + half * k[0][i];
    if (const int s = f(t + half, y, k[1])) return s;
    for (int i = 0; i < N; ++i) y[i] = x[i] + half * k[1][i];
    if (const int s = f(t + half, y, k[2])) return s;
    for (int i = 0; i < N; ++i) y[i] = x[i] + h * k[2][i];
    if (const int s = f(t + h, y, k[3])) return s;
    for (int i = 0; i < N; ++i) x[i] += h / T(6) * (k[0][i] + T(2) * (k[1][i] + k[2][i]) + k[3][i]);
    return 0;
  }

  // df/dx of x' = (zd, zdd(z, zd)) with x = (z, zd): the row-major 2 NF x 2 NF matrix
  // [0 I; dz dzd] from d(zdd)/dz and d(zdd)/dzd, column-major NF x NF as dynamics_jacobians
  // writes them. The generated step_implicit and kinegen::Simulator both build it here.
  template <int NF, class T>
  static void _state_jacobian(const T* dz, const T* dzd, T* a) noexcept {
    for (int i = 0; i < NF; ++i)
      for (int c = 0; c < NF; ++c) {
        a[i * 2 * NF + c] = T(0);
        a[i * 2 * NF + NF + c] = T(i == c ? 1 : 0);
        a[(NF + i) * 2 * NF + c] = dz[c * NF + i];
        a[(NF + i) * 2 * NF + NF + c] = dzd[c * NF + i];
      }
  }

  // df/dx (N x N, row-major: jac[i * N + j] = d f_i / d x_j) by forward differences, the
  // fallback where no exact Jacobian is at hand: step sqrt(eps) max(|x_j|, scale_j), about
  // sqrt(eps) relative accuracy, which Newton on the stages needs no more than. fx = f(t, x).
  template <int N, class T, class F>
  static int _difference_jacobian(T t, const T* x, const T* fx, const _real<T>* scale, T* jac,
                                  F&& f) noexcept {
    using R = _real<T>;
    const R root_eps = std::sqrt(std::numeric_limits<R>::epsilon());
    T y[N], fy[N];
    for (int i = 0; i < N; ++i) y[i] = x[i];
    for (int j = 0; j < N; ++j) {
      const R size = _mag(x[j]) > scale[j] ? _mag(x[j]) : scale[j];
      const T d = T(root_eps * size);
      y[j] = x[j] + d;
      if (const int s = f(t, y, fy)) return s;
      for (int i = 0; i < N; ++i) jac[i * N + j] = (fy[i] - fx[i]) / d;
      y[j] = x[j];
    }
    return 0;
  }

  // One step over h of the two-stage SDIRK of Alexander (1977): gamma = 1 - 1/sqrt(2),
  // c = (gamma, 1), a = [gamma 0; 1 - gamma gamma], b = the last row, so L-stable (stiff
  // springs decay, never ring) and of order 2. Stage i solves Y = x + h (sum a_ij k_j), k_i =
  // f(t + c_i h, Y_i), by simplified Newton on (I - h gamma J) dY = -G(Y) with J = df/dx at
  // (t, x): jacobian(t, x, fx, J) fills it (row-major) from fx = f(t, x) and returns 0 or a
  // status. Newton stops when the largest |dY_i| / scale_i is at most tolerance, or fails with
  // status 1 after max_iterations; 2 when I - h gamma J is singular. x (N values) in place,
  // unchanged on failure. iterations (optional) receives the Newton iterations taken.
  template <int N, class T, class F, class J>
  static int _sdirk2_step(T t, T h, T* x, const _real<T>* scale, F&& f, J&& jacobian,
                          int max_iterations, _real<T> tolerance,
                          int* iterations = nullptr) noexcept {
    using R = _real<T>;
    const R g = R(1) - std::sqrt(R(2)) / R(2);
    T fx[N], jac[N * N], a[N * N], k1[N], y[N], fy[N], r[N];
    int piv[N];
    if (const int s = f(t, x, fx)) return s;
    if (const int s = jacobian(t, x, fx, jac)) return s;
    for (int i = 0; i < N * N; ++i) a[i] = -T(h * g) * jac[i];
    for (int i = 0; i < N; ++i) a[i * N + i] += T(1);
    const R ratio = _lu_factor<N>(a, piv);
    if (!(ratio == ratio)) return _kStatusNonFinite;
    if (!(ratio > R(0))) return _kStatusSingular;
    int taken = 0;
    // Stage i: base = x + h sum_{j<i} a_ij k_j; Y from the explicit guess base + h g f(t, x).
    for (int stage = 0; stage < 2; ++stage) {
      const T tc = stage == 0 ? t + T(g) * h : t + h;
      T base[N];
      for (int i = 0; i < N; ++i) base[i] = stage == 0 ? x[i] : x[i] + h * T(R(1) - g) * k1[i];
      for (int i = 0; i < N; ++i) y[i] = base[i] + h * T(g) * fx[i];
      bool converged = false;
      for (int it = 0; it < max_iterations && !converged; ++it, ++taken) {
        if (const int s = f(tc, y, fy)) return s;
        for (int i = 0; i < N; ++i) r[i] = base[i] + h * T(g) * fy[i] - y[i];  // -G(Y)
        _lu_solve<N>(a, piv, r);
        R size = R(0);
        for (int i = 0; i < N; ++i) {
          y[i] += r[i];
          const R s = _mag(r[i]) / scale[i];
          size = s > size ? s : size;
        }
        if (!(size == size)) return _kStatusNonFinite;
        converged = size <= tolerance;
      }
      if (!converged) return _kStatusMaxIterations;
      // k_i from the converged Y (no further evaluation of f): (Y - base) / (h gamma).
      if (stage == 0)
        for (int i = 0; i < N; ++i) k1[i] = (y[i] - base[i]) / (h * T(g));
    }
    for (int i = 0; i < N; ++i) x[i] = y[i];  // stiffly accurate: x_new = Y_2
    if (iterations) *iterations = taken;
    return 0;
  }
  // kinegen-kernel-end integrate
};

}  // namespace kinegen::kernels
