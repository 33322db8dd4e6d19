// Dynamics tangent kernel: the exact derivatives of the minimal-coordinates accelerations
// zdd(z, zd, u) with respect to the state and the run-time inputs, for equilibrium,
// modes and linear models. One implementation: `kinegen equilibrium / modes / linearize`
// (analysis/tangent.cpp) call it with solves on their factorization of Phi_q, a
// generated header with its block solves.
//
// The equations at a solved state: Phi(q, t, w) = 0, Phi_q qd = nu(q, t, w),
// Phi_q qdd = gamma(q, qd, t, w), M(q) qdd + h(q, qd) + Phi_q^T lambda = Q^A(q, qd, t, w), with
// w the run-time inputs' slots (a free item's z, zd, zdd; an input driver's value, rate and
// acceleration; a load's input) and lambda 0 on the free rows. Differentiated along one slot
// (zdd held free): dq = -Phi_q^-1 Phi_w (= B e_k for z_k), dqd = -Phi_q^-1 r_v with
// r_v = (Phi_q qd)_q dq - nu_q dq - nu_w, the acceleration residual
// r_a = (Phi_q qdd)_q dq - gamma_q dq - gamma_qd dqd - gamma_w, so that dqdd = B dzdd - Phi_q^-1
// r_a; projected on B (B^T Phi_q^T = E^T kills d lambda on the non-free rows, and lambda's free
// rows are 0): M_z dzdd = -B^T f + Y^T r_a with Y = Phi_q^-T M B and
// f = d(M qdd + h) + (Phi_q^T lambda)_q dq - Q^A_q dq - Q^A_qd dqd - Q^A_w. The second
// derivatives are Phi_qq contracted with qd, qdd and lambda; the rest are sparse matrices the
// symbolic stage derives (symbolic/tangent.hpp). See report.hpp for how kernel files are used.
#pragma once

#include "kinegen/kernels/dynamics.hpp"

namespace kinegen::kernels {

struct LinearizeKernel : DynamicsKernel {
  // kinegen-kernel-begin linearize
  // _TangentPoint::known's code for a direction that moves neither q nor qd.
  static constexpr int _kStill = -2;
  // A sparse matrix: n entries (row[e], col[e], value[e]).
  template <class T>
  struct _Sparse {
    int n = 0;
    const int* row = nullptr;
    const int* col = nullptr;
    const T* value = nullptr;
  };
  // Phi's second derivatives d^2 Phi_row / dq_j dq_k for j <= k.
  template <class T>
  struct _Hessian {
    int n = 0;
    const int* row = nullptr;
    const int* j = nullptr;
    const int* k = nullptr;
    const T* value = nullptr;
  };
  // A solved state and the derivatives there.
  template <class T>
  struct _TangentPoint {
    int nq = 0, nf = 0, nb = 0;
    const T* q = nullptr;  // the state: q, qd and the accelerations qdd
    const T* qd = nullptr;
    const T* qdd = nullptr;
    const T* b = nullptr;     // dq/dz, nq x nf (column k at b + k nq)
    const T* mass = nullptr;  // per body, as _mass_times reads them
    const T* inertia = nullptr;
    const T* ax = nullptr;
    const T* ay = nullptr;
    const T* applied = nullptr;  // Q^A at the state (nq)
    // Optional, from a dynamics() at this state (nullptr: computed here): M B (nq x nf) and
    // B^T M B's LDL^T factors (_ldlt_factor's, nf x nf), the same operations' numbers.
    const T* mb = nullptr;
    const T* mz = nullptr;
    // Optional (nullptr: every direction solved), per direction: k < nf when it is free
    // coordinate k's value z_k (dq = B e_k), nf + k when it is its rate zd_k (dq = 0, dqd =
    // B e_k), _kStill for a slot that Phi, nu and gamma do not read (a load's input: dq = dqd
    // = 0, r_a = 0), -1 otherwise. Exact: a free item's row is quantity - z or |d|^2 - z^2, so
    // its Phi_z and nu_zd are B's right-hand side, and the solves they spare gave B's numbers;
    // the terms a zero dq or dqd would multiply are skipped (only a zero's sign can differ,
    // and a derivative that is not finite there is not multiplied by that zero).
    const int* known = nullptr;
    // Optional (n_r_rows -1: all): the n_r_rows rows r_a can be non-zero on (those of Phi_qq,
    // gamma_q, gamma_qd and gamma_w), so that Y^T r_a skips the others.
    int n_r_rows = -1;
    const int* r_rows = nullptr;
    _Hessian<T> phi_qq;
    _Sparse<T> nu_q, gamma_q, gamma_qd, phi_w, nu_w, gamma_w, applied_q, applied_qd, applied_w;
  };

  // out += s a x.
  template <class T>
  static void _sparse_add(const _Sparse<T>& a, const T& s, const T* x, T* out) noexcept {
    for (int e = 0; e < a.n; ++e) out[a.row[e]] += s * a.value[e] * x[a.col[e]];
  }
  // out += s times column `col` of a.
  template <class T>
  static void _sparse_column(const _Sparse<T>& a, int col, const T& s, T* out) noexcept {
    for (int e = 0; e < a.n; ++e)
      if (a.col[e] == col) out[a.row[e]] += s * a.value[e];
  }
  // out += (Phi_q v)_q dq: row r gets sum_jk Phi_r,jk v_j dq_k.
  template <class T>
  static void _hessian_times(const _Hessian<T>& h, const T* v, const T* dq, T* out) noexcept {
    for (int e = 0; e < h.n; ++e) {
      const int j = h.j[e], k = h.k[e];
      T s = v[j] * dq[k];
      if (j != k) s += v[k] * dq[j];
      out[h.row[e]] += h.value[e] * s;
    }
  }
  // out += (Phi_q^T lambda)_q dq: coordinate j gets sum_rk lambda_r Phi_r,jk dq_k.
  template <class T>
  static void _hessian_transposed(const _Hessian<T>& h, const T* lambda, const T* dq,
                                  T* out) noexcept {
    for (int e = 0; e < h.n; ++e) {
      const int j = h.j[e], k = h.k[e];
      const T s = lambda[h.row[e]] * h.value[e];
      out[j] += s * dq[k];
      if (j != k) out[k] += s * dq[j];
    }
  }

  // out = M qdd + h(q, qd), the inertia forces' negative: per body the centre of mass's
  // acceleration (xdd - alpha ay - w^2 ax, ydd + alpha ax - w^2 ay) times m, and about the
  // frame's origin (ax, ay) x that + j alpha. Extra coordinates' rows are 0. With c, also
  // their derivatives at fixed qdd, 5 numbers per body: each body's forces depend on q only
  // through its angle (d(ax, ay)/dphi = (-ay, ax)) and on qd through its w (the w^2 terms):
  // d(fx, fy, the moment)/dphi and -d(fx, fy)/dw, for _inertia_tangent.
  template <class T>
  static void _inertia_forces(int num_b, int num_q, const T* m, const T* j, const T* ax,
                              const T* ay, const T* qd, const T* qdd, T* out,
                              T* c = nullptr) noexcept {
    for (int b = 0; b < num_b; ++b) {
      // Read before any write: out and c may alias the inputs as far as the compiler knows.
      const T w = qd[3 * b + 2], alpha = qdd[3 * b + 2], mb = m[b], x = ax[b], y = ay[b];
      const T fx = mb * (qdd[3 * b] - alpha * y - w * w * x);
      const T fy = mb * (qdd[3 * b + 1] + alpha * x - w * w * y);
      out[3 * b] = fx;
      out[3 * b + 1] = fy;
      out[3 * b + 2] = x * fy - y * fx + j[b] * alpha;
      if (c) {
        c[5 * b] = mb * (w * w * y - alpha * x);
        c[5 * b + 1] = -mb * (alpha * y + w * w * x);
        c[5 * b + 2] = -y * fy - x * fx;
        c[5 * b + 3] = T(2) * mb * w * x;
        c[5 * b + 4] = T(2) * mb * w * y;
      }
    }
    for (int k = 3 * num_b; k < num_q; ++k) out[k] = T(0);
  }
  // out += d(M qdd + h)/dq dq + dh/dqd dqd from _inertia_forces' c; dq or dqd may be nullptr:
  // 0. Always inlined, as _tangent_residuals (below).
  template <class T>
  KINEGEN_ALWAYS_INLINE static void _inertia_tangent(int num_b, const T* ax, const T* ay,
                                                     const T* c, const T* dq, const T* dqd,
                                                     T* out) noexcept {
    for (int b = 0; b < num_b; ++b) {
      T dfx = T(0), dfy = T(0), dn = T(0);
      if (dq) {
        const T dphi = dq[3 * b + 2];
        dfx = c[5 * b] * dphi;
        dfy = c[5 * b + 1] * dphi;
        dn = c[5 * b + 2] * dphi;
      }
      if (dqd) {
        const T dw = dqd[3 * b + 2];
        dfx -= c[5 * b + 3] * dw;
        dfy -= c[5 * b + 4] * dw;
      }
      const T moment = dn + ax[b] * dfy - ay[b] * dfx;
      out[3 * b] += dfx;
      out[3 * b + 1] += dfy;
      out[3 * b + 2] += moment;
    }
  }

  // The work space _dynamics_tangent needs for ndir directions, in T's.
  static constexpr int _tangent_work_size(int num_q, int num_f, int ndir) noexcept {
    return num_q * num_f + num_q * (num_f + 1) + num_f * num_f + 3 * num_q * ndir +
           num_q * (ndir > num_f + 1 ? ndir : num_f + 1) + 2 * num_q;
  }

  // d(zdd)/d(w_slot) for each of the ndir slots (slots[i]: a free item's z or zd, or a
  // run-time input's; never a zdd), into dzdd (nf per slot, slot i's at dzdd + i nf).
  // solve(b, x, m) solves Phi_q X = B for m columns (each nq long), solve_transposed(b, y, m)
  // Phi_q^T Y = B (B by coordinate, Y by row); b may be left changed, x and y are apart from
  // it; both return 0 or their status. Three calls at most (nf + 1 transposed columns, then
  // the directions' dq, then their dqd), so that a solver factors Phi_q's blocks once per
  // call. work: _tangent_work_size T's. Returns 0; 2 when M_z = B^T M B is not positive
  // definite; 3 when a value is not finite; or a solve's status. NQ, NF, NB: p's sizes when
  // known at compile time (a generated header's), 0 when not: the loops then have fixed
  // lengths. Always inlined (GCC, Clang): only then do the caller's constant tables (a
  // header's sparsity patterns) fold into the loops.
  template <int NQ = 0, int NF = 0, int NB = 0, class T, class Solve, class SolveTransposed>
  KINEGEN_ALWAYS_INLINE static int _dynamics_tangent(const _TangentPoint<T>& p, int ndir,
                                                     const int* slots, T* dzdd, T* work,
                                                     Solve&& solve,
                                                     SolveTransposed&& solve_transposed) noexcept {
    const int num_q = NQ > 0 ? NQ : p.nq, num_f = NF > 0 ? NF : p.nf, num_b = NB > 0 ? NB : p.nb;
    T* mb = work;
    T* y = mb + num_q * num_f;  // Phi_q^-T M B, then lambda in column nf
    T* mz = y + num_q * (num_f + 1);
    T* dq = mz + num_f * num_f;
    T* dqd = dq + num_q * ndir;
    T* x = dqd + num_q * ndir;  // solutions, side by side
    T* rhs = x + num_q * ndir;  // their right-hand sides (nf + 1 columns for the transposed)
    // _inertia_forces' 5 numbers per body: 5 nb <= 2 nq, as every body has 3 coordinates.
    T* inertia = rhs + num_q * (ndir > num_f + 1 ? ndir : num_f + 1);
    const T* m_b = p.mb;  // M B and B^T M B's factors: dynamics()' or computed here
    const T* m_z = p.mz;
    if (!m_b || !m_z) {
      for (int k = 0; k < num_f; ++k)
        _mass_times(num_b, num_q, p.mass, p.inertia, p.ax, p.ay, p.b + k * num_q, mb + k * num_q);
      for (int i = 0; i < num_f; ++i)
        for (int k = 0; k < num_f; ++k)
          mz[i * num_f + k] = _dot(num_q, p.b + i * num_q, mb + k * num_q);
      const _real<T> ratio = _ldlt_factor(num_f, mz);
      if (!(ratio > _real<T>(0))) return ratio == ratio ? _kStatusSingular : _kStatusNonFinite;
      m_b = mb;
      m_z = mz;
    }
    // Y = Phi_q^-T M B; lambda from Phi_q^T lambda = Q^A - (M qdd + h).
    const T* lambda = y + num_q * num_f;
    for (int k = 0; k < num_q * num_f; ++k) rhs[k] = m_b[k];
    _inertia_forces(num_b, num_q, p.mass, p.inertia, p.ax, p.ay, p.qd, p.qdd, x, inertia);
    for (int k = 0; k < num_q; ++k) rhs[num_q * num_f + k] = p.applied[k] - x[k];
    if (const int s = solve_transposed(rhs, y, num_f + 1)) return s;
    if (const int s = _tangent_motions(p, num_q, num_f, ndir, slots, dq, dqd, rhs, x, solve))
      return s;
    // Stage by stage across the directions, each direction's r and f apart (in x and rhs,
    // free now), so that the directions' chains of dependent operations overlap.
    T* r = x;
    T* f = rhs;
    for (int i = 0; i < ndir; ++i)
      _tangent_residuals(p, num_q, num_b, slots[i], lambda, inertia,
                         _moved(p, num_q, num_f, i, dq, false),
                         _moved(p, num_q, num_f, i, dqd, true), r + i * num_q, f + i * num_q);
    // y_k . r over r's rows that can be non-zero (p.r_rows) when known.
    const auto y_dot_r = [&](int k, const T* ri) {
      if (p.n_r_rows < 0) return _dot(num_q, y + k * num_q, ri);
      T s = T(0);
      for (int e = 0; e < p.n_r_rows; ++e) s += y[k * num_q + p.r_rows[e]] * ri[p.r_rows[e]];
      return s;
    };
    for (int i = 0; i < ndir; ++i)
      for (int k = 0; k < num_f; ++k)
        dzdd[i * num_f + k] =
            (p.known && p.known[i] == _kStill ? T(0) : y_dot_r(k, r + i * num_q)) -
            _dot(num_q, p.b + k * num_q, f + i * num_q);
    for (int i = 0; i < ndir; ++i) _ldlt_solve(num_f, m_z, dzdd + i * num_f);
    for (int k = 0; k < num_f * ndir; ++k)
      if (!_finite(_mag(dzdd[k]))) return _kStatusNonFinite;
    return _kStatusConverged;
  }

  // Direction i's dq (rate: dqd): B's column when known, nullptr when known to be 0, else its
  // solution at d + i nq.
  template <class T>
  KINEGEN_ALWAYS_INLINE static const T* _moved(const _TangentPoint<T>& p, int num_q, int num_f,
                                               int i, const T* d, bool rate) noexcept {
    const int k = p.known ? p.known[i] : -1;
    if (_solves(p, num_f, i, rate)) return d + i * num_q;
    if (k == _kStill || (rate ? k < num_f : k >= num_f)) return nullptr;
    return p.b + (rate ? k - num_f : k) * num_q;
  }

  // Whether direction i needs a solve for its dq (rate: dqd); the others are B's columns or 0.
  template <class T>
  KINEGEN_ALWAYS_INLINE static bool _solves(const _TangentPoint<T>& p, int num_f, int i,
                                            bool rate) noexcept {
    const int k = p.known ? p.known[i] : -1;
    return k == -1 || (rate && k >= 0 && k < num_f);
  }

  // Each direction's dq = -Phi_q^-1 Phi_w and dqd = -Phi_q^-1 r_v, as _dynamics_tangent
  // describes them, in two solves (of the columns not known: _moved), with rhs and x as their
  // work space; 0 or the solve's status.
  template <class T, class Solve>
  KINEGEN_ALWAYS_INLINE static int _tangent_motions(const _TangentPoint<T>& p, int num_q, int num_f,
                                                    int ndir, const int* slots, T* dq, T* dqd,
                                                    T* rhs, T* x, Solve&& solve) noexcept {
    // Where the m solutions go: straight to d + i nq when the directions that need them are
    // consecutive (a model's z's, say), else to x, and then scattered (no copy, same numbers).
    const auto target = [&](T* d, bool rate) {
      int first = -1, last = -1, count = 0;
      for (int i = 0; i < ndir; ++i)
        if (_solves(p, num_f, i, rate)) {
          if (first < 0) first = i;
          last = i;
          ++count;
        }
      return last - first + 1 == count ? d + first * num_q : nullptr;
    };
    const auto scatter = [&](T* d, bool rate) {
      for (int i = 0, n = 0; i < ndir; ++i)
        if (_solves(p, num_f, i, rate))
          for (int k = 0; k < num_q; ++k) d[i * num_q + k] = x[n++];
    };
    const auto zero = [&](T* v) {
      for (int k = 0; k < num_q; ++k) v[k] = T(0);
    };
    int m = 0;
    for (int i = 0; i < ndir; ++i) {
      if (!_solves(p, num_f, i, false)) continue;
      T* v = rhs + m++ * num_q;
      zero(v);
      _sparse_column(p.phi_w, slots[i], T(-1), v);
    }
    if (m > 0) {
      T* direct = target(dq, false);
      if (const int s = solve(rhs, direct ? direct : x, m)) return s;
      if (!direct) scatter(dq, false);
    }
    m = 0;
    for (int i = 0; i < ndir; ++i) {
      if (!_solves(p, num_f, i, true)) continue;
      T* v = rhs + m++ * num_q;
      zero(v);
      if (const T* d = _moved(p, num_q, num_f, i, dq, false)) {
        _hessian_times(p.phi_qq, p.qd, d, v);
        _sparse_add(p.nu_q, T(-1), d, v);
      }
      _sparse_column(p.nu_w, slots[i], T(-1), v);
      for (int k = 0; k < num_q; ++k) v[k] = -v[k];
    }
    if (m > 0) {
      T* direct = target(dqd, true);
      if (const int s = solve(rhs, direct ? direct : x, m)) return s;
      if (!direct) scatter(dqd, true);
    }
    return 0;
  }

  template <class T>
  static T _dot(int n, const T* a, const T* b) noexcept {
    T s = T(0);
    for (int k = 0; k < n; ++k) s += a[k] * b[k];
    return s;
  }

  // One direction's acceleration residual r (r_a) and force f, as _dynamics_tangent describes
  // them, from its dq and dqd (nullptr: 0, and the terms they multiply skipped). Always inlined:
  // Clang kept it apart, where the sparsity tables do not fold (4x slower on the pendulum).
  template <class T>
  KINEGEN_ALWAYS_INLINE static void _tangent_residuals(const _TangentPoint<T>& p, int num_q,
                                                       int num_b, int slot, const T* lambda,
                                                       const T* inertia, const T* dq, const T* dqd,
                                                       T* r, T* f) noexcept {
    for (int k = 0; k < num_q; ++k) r[k] = f[k] = T(0);
    if (dq) {
      _hessian_times(p.phi_qq, p.qdd, dq, r);
      _sparse_add(p.gamma_q, T(-1), dq, r);
    }
    if (dqd) _sparse_add(p.gamma_qd, T(-1), dqd, r);
    _sparse_column(p.gamma_w, slot, T(-1), r);
    _inertia_tangent(num_b, p.ax, p.ay, inertia, dq, dqd, f);
    if (dq) {
      _hessian_transposed(p.phi_qq, lambda, dq, f);
      _sparse_add(p.applied_q, T(-1), dq, f);
    }
    if (dqd) _sparse_add(p.applied_qd, T(-1), dqd, f);
    _sparse_column(p.applied_w, slot, T(-1), f);
  }
  // kinegen-kernel-end linearize
};

}  // namespace kinegen::kernels
