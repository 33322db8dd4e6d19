// Block-solver kernel: linear systems with Phi_q through its block-lower-triangular structure,
// driven by the model's structure tables. It serves the solves that follow a position solve
// with right-hand sides other than nu and gamma: Phi_q X = B for parameter sensitivities
// (forward through the blocks) and Phi_q^T Y = B for kinetostatics (backward). See report.hpp
// for how kernel files are used.
#pragma once

#include <type_traits>

#include "kinegen/kernels/lu.hpp"

namespace kinegen::kernels {

struct BlockLinearKernel : LuKernel {
  // kinegen-kernel-begin block_linear
  // S is the model; it gives the structure tables: block_begin (num_blocks + 1 offsets into
  // block_rows and block_cols, which list each block's rows and coordinates in solve order),
  // coordinate_block and coordinate_slot (each coordinate's block and place in block_cols),
  // jac_row_begin (each row's first entry of jac_rows / jac_cols, which are sorted by row),
  // and coordinate_scales. jac holds Phi_q at those entries. Each block is factored once for
  // all m right-hand sides; a singular, ill-conditioned (rcond below options.min_rcond) or
  // non-finite block fails with status 2 or 3 and its index, and the report's rcond is the
  // smallest of any block.

  // Calls f(std::integral_constant<int, K>) for K == n, 1 <= n <= S::max_block_size, so that
  // each block size gets the fixed-size LU.
  template <class S, int K = 1, class F>
  static void _with_block_size(int n, F&& f) noexcept {
    if constexpr (K <= S::max_block_size) {
      if (n == K) {
        f(std::integral_constant<int, K>{});
      } else {
        _with_block_size<S, K + 1>(n, f);
      }
    }
  }

  // Gathers block k (K x K, row-major: its rows by its coordinates) from jac and factors it.
  // False when it is singular, ill-conditioned or not finite (r records why).
  template <class S, int K, class T, class R>
  static bool _block_factor(int k, const T* jac, T* a, int* piv, BlockReport<R>& r,
                            const R& min_rcond) noexcept {
    const int b0 = S::block_begin[k];
    for (int i = 0; i < K * K; ++i) a[i] = T(0);
    for (int i = 0; i < K; ++i) {
      const int row = S::block_rows[b0 + i];
      for (int e = S::jac_row_begin[row]; e < S::jac_row_begin[row + 1]; ++e) {
        const int c = S::jac_cols[e];
        if (S::coordinate_block[c] == k) a[i * K + (S::coordinate_slot[c] - b0)] = jac[e];
      }
    }
    R d[K], row_max[K];
    for (int j = 0; j < K; ++j) d[j] = R(S::coordinate_scales[S::block_cols[b0 + j]]);
    _row_max<K>(a, d, row_max);
    const R ratio = _lu_factor<K>(a, piv);
    if (!(ratio == ratio)) {
      r = _fail(r, 3, k);
      return false;
    }
    const R rcond = ratio > 0 ? _lu_rcond<K>(a, piv, row_max, d) : R(0);
    r.rcond = std::min(r.rcond, rcond);
    if (!(rcond > min_rcond)) {
      r = _fail(r, rcond == rcond ? 2 : 3, k);
      return false;
    }
    return true;
  }

  // Phi_q X = B: x and b hold m columns (column j at x + j * nq, b + j * nq; x must not
  // overlap b). Blocks in solve order; row r of block k subtracts its entries in earlier
  // blocks' coordinates, which are solved by then.
  template <class S, class T, class R>
  static BlockReport<R> _block_forward(const T* jac, const T* b, T* x, int m,
                                       const BasicBlockOptions<R>& o) noexcept {
    BlockReport<R> r;
    bool ok = true;
    for (int k = 0; ok && k < S::num_blocks; ++k) {
      const int b0 = S::block_begin[k];
      _with_block_size<S>(S::block_begin[k + 1] - b0, [&](auto size) {
        constexpr int K = decltype(size)::value;
        T a[K * K];
        int piv[K];
        if (!(ok = _block_factor<S, K>(k, jac, a, piv, r, o.min_rcond))) return;
        for (int col = 0; col < m; ++col) {
          const T* bc = b + col * S::nq;
          T* xc = x + col * S::nq;
          T v[K];
          for (int i = 0; i < K; ++i) {
            const int row = S::block_rows[b0 + i];
            v[i] = bc[row];
            for (int e = S::jac_row_begin[row]; e < S::jac_row_begin[row + 1]; ++e) {
              const int c = S::jac_cols[e];
              if (S::coordinate_block[c] != k) v[i] -= jac[e] * xc[c];
            }
          }
          _lu_solve<K>(a, piv, v);
          // A non-finite right-hand side or entry outside the block shows only here.
          if (!(ok = _all_finite<K>(v))) {
            r = _fail(r, 3, k);
            return;
          }
          for (int j = 0; j < K; ++j) xc[S::block_cols[b0 + j]] = v[j];
        }
      });
    }
    return r;
  }

  // Phi_q^T Y = B: y (by row) and b (by coordinate) hold m columns as in _block_forward; b is
  // used as work space and left changed. Blocks in reverse order: block k's coordinates'
  // equations involve only its own and later blocks' rows, and once its rows' y are known
  // they are subtracted from the equations of earlier blocks' coordinates.
  template <class S, class T, class R>
  static BlockReport<R> _block_transposed(const T* jac, T* b, T* y, int m,
                                          const BasicBlockOptions<R>& o) noexcept {
    BlockReport<R> r;
    bool ok = true;
    for (int k = S::num_blocks - 1; ok && k >= 0; --k) {
      const int b0 = S::block_begin[k];
      _with_block_size<S>(S::block_begin[k + 1] - b0, [&](auto size) {
        constexpr int K = decltype(size)::value;
        T a[K * K];
        int piv[K];
        if (!(ok = _block_factor<S, K>(k, jac, a, piv, r, o.min_rcond))) return;
        for (int col = 0; col < m; ++col) {
          T* bc = b + col * S::nq;
          T* yc = y + col * S::nq;
          T v[K];
          for (int j = 0; j < K; ++j) v[j] = bc[S::block_cols[b0 + j]];
          _lu_solve_transposed<K>(a, piv, v);
          if (!(ok = _all_finite<K>(v))) {
            r = _fail(r, 3, k);
            return;
          }
          for (int i = 0; i < K; ++i) {
            const int row = S::block_rows[b0 + i];
            yc[row] = v[i];
            for (int e = S::jac_row_begin[row]; e < S::jac_row_begin[row + 1]; ++e) {
              const int c = S::jac_cols[e];
              if (S::coordinate_block[c] != k) bc[c] -= jac[e] * v[i];
            }
          }
        }
      });
    }
    return r;
  }
  // kinegen-kernel-end block_linear
};

}  // namespace kinegen::kernels
