// Block-solver kernel: a fixed-size LU with partial pivoting (row-major K x K), its solve, the
// sign of the determinant and a condition estimate. See report.hpp for how kernel files are
// used.
#pragma once

#include <algorithm>
#include <utility>

#include "kinegen/kernels/report.hpp"

namespace kinegen::kernels {

struct LuKernel : ReportKernel {
  // kinegen-kernel-begin lu
  // In-place LU with partial pivoting; returns smallest / largest |pivot| (0 when singular,
  // NaN when a value is not finite). The diagonal keeps the pivots' reciprocals, so that
  // _lu_solve multiplies: a division costs several multiplications' time, and a step solves
  // with each factorization more than once.
  template <int K, class T>
  static _real<T> _lu_factor(T* a, int* piv) noexcept {
    using R = _real<T>;
    if constexpr (K == 2) {
      // The loop below for K = 2, written out: small enough to be inlined (a loop of two
      // bodies is the most common block).
      const bool swap = _mag(a[2]) > _mag(a[0]);
      piv[0] = swap ? 1 : 0;
      piv[1] = 1;
      if (swap) {
        std::swap(a[0], a[2]);
        std::swap(a[1], a[3]);
      }
      const R p0 = _mag(a[0]);
      if (!(p0 > 0)) return p0;  // 0, or NaN
      const T i0 = T(1) / a[0];
      const T f = a[2] * i0;
      a[2] = f;
      a[3] -= f * a[1];
      const R p1 = _mag(a[3]);
      if (!(p1 > 0)) return p1;
      const T i1 = T(1) / a[3];
      a[0] = i0;
      a[3] = i1;
      return p0 < p1 ? p0 * _mag(i1) : p1 * _mag(i0);  // the ratio without a third division
    }
    R largest = 0, smallest = 0;
    for (int k = 0; k < K; ++k) {
      int m = k;
      R best = _mag(a[k * K + k]);
      for (int i = k + 1; i < K; ++i) {
        const R v = _mag(a[i * K + k]);
        if (v > best) {
          best = v;
          m = i;
        }
      }
      if (!(best == best)) return best;
      piv[k] = m;
      if (m != k)
        for (int j = 0; j < K; ++j) std::swap(a[k * K + j], a[m * K + j]);
      if (best == 0) return 0;
      largest = k == 0 ? best : std::max(largest, best);
      smallest = k == 0 ? best : std::min(smallest, best);
      const T inv = T(1) / a[k * K + k];
      a[k * K + k] = inv;
      for (int i = k + 1; i < K; ++i) {
        const T f = a[i * K + k] * inv;
        a[i * K + k] = f;
        for (int j = k + 1; j < K; ++j) a[i * K + j] -= f * a[k * K + j];
      }
    }
    return smallest / largest;
  }
  template <int K, class T>
  static void _lu_solve(const T* a, const int* piv, T* b) noexcept {
    if constexpr (K == 1) {  // no exchange; the loops below would index past b
      b[0] *= a[0];
      return;
    }
    if constexpr (K == 2) {  // the loops below, written out (the same operations)
      if (piv[0] != 0) std::swap(b[0], b[1]);
      b[1] = (b[1] - a[2] * b[0]) * a[3];
      b[0] = (b[0] - a[1] * b[1]) * a[0];
      return;
    }
    // _lu_factor swaps whole rows (multipliers included), so b takes every swap first.
    for (int k = 0; k < K; ++k)
      if (piv[k] != k) std::swap(b[k], b[piv[k]]);
    for (int k = 0; k < K; ++k)
      for (int i = k + 1; i < K; ++i) b[i] -= a[i * K + k] * b[k];
    for (int k = K - 1; k >= 0; --k) {
      for (int j = k + 1; j < K; ++j) b[k] -= a[k * K + j] * b[j];
      b[k] *= a[k * K + k];  // the pivot's reciprocal
    }
  }
  // Solves A^T y = b with A's factors (P A = L U, so A^T = U^T L^T P): U^T w = b forward, then
  // L^T v = w backward, then the row exchanges undone in reverse order. For Phi_q^T lambda = Q
  // with the factorization the forward solves use.
  template <int K, class T>
  static void _lu_solve_transposed(const T* a, const int* piv, T* b) noexcept {
    if constexpr (K == 1) {  // no exchange; the loops below would index past b
      b[0] *= a[0];
      return;
    }
    for (int k = 0; k < K; ++k) {
      for (int j = 0; j < k; ++j) b[k] -= a[j * K + k] * b[j];
      b[k] *= a[k * K + k];  // the pivot's reciprocal
    }
    for (int k = K - 1; k >= 0; --k)
      for (int i = k + 1; i < K; ++i) b[k] -= a[i * K + k] * b[i];
    for (int k = K - 1; k >= 0; --k)
      if (piv[k] != k) std::swap(b[k], b[piv[k]]);
  }
  // Sign of the determinant of the factored matrix: the pivots' signs, and one per row exchange.
  template <int K, class T>
  static int _lu_det_sign(const T* a, const int* piv) noexcept {
    int sign = 1;
    for (int k = 0; k < K; ++k) {
      if (piv[k] != k) sign = -sign;
      if (_re(a[k * K + k]) < 0) sign = -sign;
    }
    return sign;
  }
  // Largest |a_ij| d_j of each row i of a K x K matrix (before _lu_factor): the row scales of
  // the equilibrated matrix diag(1 / row_max) a diag(d), d the columns' scales.
  template <int K, class T>
  static void _row_max(const T* a, const _real<T>* d, _real<T>* row_max) noexcept {
    for (int i = 0; i < K; ++i) {
      row_max[i] = 0;
      for (int j = 0; j < K; ++j) row_max[i] = std::max(row_max[i], _mag(a[i * K + j]) * d[j]);
    }
  }
  // 1 / |A^-1|_inf of the equilibrated A = diag(1 / row_max) J diag(d), from J's factors
  // (A^-1 = diag(1 / d) J^-1 diag(row_max), column by column). |A|_inf is between 1 and K, so
  // this is the reciprocal condition number in the infinity norm within a factor K.
  template <int K, class T>
  static _real<T> _lu_rcond(const T* a, const int* piv, const _real<T>* row_max,
                            const _real<T>* d) noexcept {
    using R = _real<T>;
    R sums[K] = {};
    if constexpr (K == 2) {
      // The loop below for K = 2, written out from the factors: J^-1 = U^-1 L^-1 P, with
      // a = {1 / u00, u01, l10, 1 / u11}, P the row exchange.
      const T m01 = -a[1] * a[0] * a[3];
      const T m[4] = {a[0] - m01 * a[2], m01, -a[2] * a[3], a[3]};
      const int c0 = piv[0], c1 = 1 - piv[0];  // the columns of m that are J^-1's 0 and 1
      sums[0] = _mag(m[c0]) * row_max[0] + _mag(m[c1]) * row_max[1];
      sums[1] = _mag(m[2 + c0]) * row_max[0] + _mag(m[2 + c1]) * row_max[1];
    } else {
      for (int j = 0; j < K; ++j) {
        T x[K] = {};
        x[j] = T(1);
        _lu_solve<K>(a, piv, x);
        for (int i = 0; i < K; ++i) sums[i] += _mag(x[i]) * row_max[j];
      }
    }
    R norm = 0;
    for (int i = 0; i < K; ++i) norm = std::max(norm, sums[i] / d[i]);
    return norm > 0 ? R(1) / norm : R(0);
  }
  // kinegen-kernel-end lu
};

}  // namespace kinegen::kernels
