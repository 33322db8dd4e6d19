// Dynamics kernel: the pieces of the minimal-coordinates equations of motion that do not
// depend on the model's structure. The generalized mass matrix as a product
// (M v, from each body's mass, inertia and rotated centre of mass), a pivot-free LDL^T of the
// small, symmetric reduced mass M_z = B^T M B, and the reduction itself:
// M_z zdd = B^T (Q^A + the inertia forces at qdd = c), qdd = c + B zdd.
// The command line's `simulate` (analysis/dynamics.cpp) and a generated header's dynamics()
// both call these, so the reduction is written once. See report.hpp for how kernel files are
// used.
#pragma once

#include "kinegen/kernels/report.hpp"

namespace kinegen::kernels {

struct DynamicsKernel : ReportKernel {
  // kinegen-kernel-begin dynamics
  // out = M v for nb bodies (each q_b = [x, y, phi] with the frame at its origin): per body
  // its mass m, inertia j about the centre of mass and the centre's offset A s = (ax, ay) in
  // global axes. The centre moves at (vx - w ay, vy + w ax), so the body's rows of M v are
  // m times that, and ax m (vy + w ax) - ay m (vx - w ay) + j w. Coordinates after the
  // bodies' (extra coordinates) carry no mass: their rows are 0.
  template <class T>
  static void _mass_times(int num_b, int num_q, const T* m, const T* j, const T* ax, const T* ay,
                          const T* v, T* out) noexcept {
    for (int b = 0; b < num_b; ++b) {
      const T& vx = v[3 * b];
      const T& vy = v[3 * b + 1];
      const T& w = v[3 * b + 2];
      const T px = m[b] * (vx - w * ay[b]);
      const T py = m[b] * (vy + w * ax[b]);
      out[3 * b] = px;
      out[3 * b + 1] = py;
      out[3 * b + 2] = ax[b] * py - ay[b] * px + j[b] * w;
    }
    for (int k = 3 * num_b; k < num_q; ++k) out[k] = T(0);
  }

  // In-place LDL^T of a symmetric positive definite n x n matrix (row-major; the lower
  // triangle is read): L below the diagonal, D's reciprocals on it. Returns the smallest over
  // the largest pivot (real parts), 0 when a pivot is not positive (a reduced mass that is
  // singular or not positive definite), NaN when a value is not finite. No pivoting: M_z is
  // positive definite wherever the free coordinates carry inertia.
  template <class T>
  static _real<T> _ldlt_factor(int n, T* a) noexcept {
    using R = _real<T>;
    R smallest = R(0), largest = R(0);
    for (int k = 0; k < n; ++k) {
      T d = a[k * n + k];
      for (int p = 0; p < k; ++p) d -= a[k * n + p] * a[k * n + p] / a[p * n + p];
      const R dr = _re(d);
      if (!_finite(_mag(d))) return dr - dr;  // NaN
      if (!(dr > R(0))) return R(0);
      smallest = k == 0 ? dr : (dr < smallest ? dr : smallest);
      largest = dr > largest ? dr : largest;
      // Rows below: l_ik = (a_ik - sum_p l_ip d_p l_kp) / d_k, with l_ip d_p kept in a_ip
      // until row i is reached (a[i * n + p] holds l_ip d_p for p < k here).
      for (int i = k + 1; i < n; ++i) {
        T s = a[i * n + k];
        for (int p = 0; p < k; ++p) s -= a[i * n + p] * a[k * n + p] / a[p * n + p];
        a[i * n + k] = s;  // l_ik d_k
      }
      a[k * n + k] = d;
    }
    // Turn l_ik d_k into l_ik and the diagonal into 1 / d_k.
    for (int k = 0; k < n; ++k) {
      const T inv = T(1) / a[k * n + k];
      for (int i = k + 1; i < n; ++i) a[i * n + k] *= inv;
      a[k * n + k] = inv;
    }
    return smallest / largest;
  }

  // Solves L D L^T x = b in place with _ldlt_factor's factors.
  template <class T>
  static void _ldlt_solve(int n, const T* a, T* b) noexcept {
    for (int i = 0; i < n; ++i)
      for (int p = 0; p < i; ++p) b[i] -= a[i * n + p] * b[p];
    for (int i = 0; i < n; ++i) b[i] *= a[i * n + i];
    for (int i = n - 1; i >= 0; --i)
      for (int p = i + 1; p < n; ++p) b[i] -= a[p * n + i] * b[p];
  }

  // The reduction: with B (nq x nf, column k at b + k nq: dq/dz_k), mb = M B (the same
  // layout), g = Q^A + the inertia forces of the motion at qdd = c (the generalized force
  // whose projection B^T g must vanish with zdd = 0 taken out), solves M_z zdd = B^T g for
  // zdd and adds B zdd to qdd (which holds c). work: nf * nf T's (receives M_z's factors).
  // Returns _ldlt_factor's pivot ratio; zdd and qdd are valid only where it is positive.
  template <class T>
  static _real<T> _reduced_accelerations(int num_q, int num_f, const T* b, const T* mb, const T* g,
                                         T* work, T* zdd, T* qdd) noexcept {
    for (int i = 0; i < num_f; ++i) {
      T r = T(0);
      for (int k = 0; k < num_q; ++k) r += b[i * num_q + k] * g[k];
      zdd[i] = r;
      for (int j = 0; j <= i; ++j) {
        T s = T(0);
        for (int k = 0; k < num_q; ++k) s += b[i * num_q + k] * mb[j * num_q + k];
        work[i * num_f + j] = s;
        work[j * num_f + i] = s;
      }
    }
    const _real<T> ratio = _ldlt_factor(num_f, work);
    if (!(ratio > _real<T>(0))) return ratio;
    _ldlt_solve(num_f, work, zdd);
    for (int i = 0; i < num_f; ++i)
      for (int k = 0; k < num_q; ++k) qdd[k] += b[i * num_q + k] * zdd[i];
    return ratio;
  }
  // kinegen-kernel-end dynamics
};

}  // namespace kinegen::kernels
