// Block-solver kernel: linear systems with Phi_q through its block-lower-triangular structure,
// driven by the model's structure tables. It serves the solves that follow a position solve
// with right-hand sides other than nu and gamma: Phi_q X = B for parameter sensitivities
// (forward through the blocks) and Phi_q^T Y = B for kinetostatics (backward). See report.hpp
// for how kernel files are used.
#pragma once

#include <type_traits>
#include <utility>

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

  // Calls f(index, size) for each block in solve order (kReverse: backwards) while it returns
  // true; false when one did not. size is the block's std::integral_constant size; index is
  // its std::integral_constant index up to _kMaxUnrolledBlocks blocks, so that each block is its
  // own instance whose loops have fixed bounds and places (which the compiler unrolls: the
  // solves after a dynamics() 2-3x faster), and beyond that an int (one loop: a header of
  // thousands of blocks compiles as before). Folded in chunks of 64 (Clang allows 256 levels).
  static constexpr int _kMaxUnrolledBlocks = 1024;
  template <class S, bool kReverse = false, class F>
  static bool _each_block_unrolled(F&& f) noexcept {
    if constexpr (S::num_blocks <= _kMaxUnrolledBlocks) {
      return _each_block_chunk<S, kReverse, 0>(f);
    } else {
      bool ok = true;
      for (int n = 0; ok && n < S::num_blocks; ++n) {
        const int k = kReverse ? S::num_blocks - 1 - n : n;
        _with_block_size<S>(S::block_begin[k + 1] - S::block_begin[k],
                            [&](auto size) { ok = f(k, size); });
      }
      return ok;
    }
  }
  template <class S, bool kReverse, int kFrom, class F>
  static bool _each_block_chunk(F& f) noexcept {
    constexpr int count = S::num_blocks - kFrom < 64 ? S::num_blocks - kFrom : 64;
    if constexpr (count <= 0) {
      return true;
    } else {
      return _each_block_in<S, kReverse, kFrom>(f, std::make_integer_sequence<int, count>{}) &&
             _each_block_chunk<S, kReverse, kFrom + count>(f);
    }
  }
  template <class S, bool kReverse, int kFrom, class F, int... I>
  static bool _each_block_in(F& f, std::integer_sequence<int, I...>) noexcept {
    constexpr int n = S::num_blocks;
    return (_call_block<S, (kReverse ? n - 1 - kFrom - I : kFrom + I)>(f) && ...);
  }
  template <class S, int k, class F>
  static bool _call_block(F& f) noexcept {
    constexpr int size = S::block_begin[k + 1] - S::block_begin[k];
    return f(std::integral_constant<int, k>{}, std::integral_constant<int, size>{});
  }

  // Gathers block k (K x K, row-major: its rows by its coordinates) from jac and factors it.
  // False when it is singular, ill-conditioned or not finite (r records why).
  // Index: int, or std::integral_constant<int, k> from _each_block_unrolled (each block its own
  // instance, with its tables' entries known to the compiler).
  template <class S, int K, class Index, class T, class R>
  static bool _block_factor(Index k, const T* jac, T* a, int* piv, BlockReport<R>& r,
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
    // Rows are equilibrated by their largest scaled entry in all of Phi_q's row, not only in
    // the block: a block entry tiny next to the rest of its row (a dead centre in a 1 x 1
    // block) is a nearly singular Phi_q, which the block on its own would not show.
    R d[K], row_max[K];
    for (int j = 0; j < K; ++j) d[j] = R(S::coordinate_scales[S::block_cols[b0 + j]]);
    for (int i = 0; i < K; ++i) {
      const int row = S::block_rows[b0 + i];
      row_max[i] = R(0);
      for (int e = S::jac_row_begin[row]; e < S::jac_row_begin[row + 1]; ++e)
        row_max[i] = std::max(row_max[i], _mag(jac[e]) * R(S::coordinate_scales[S::jac_cols[e]]));
    }
    const R ratio = _lu_factor<K>(a, piv);
    if (!(ratio == ratio)) {
      r = _fail(r, _kStatusNonFinite, k);
      return false;
    }
    const R rcond = ratio > 0 ? _lu_rcond<K>(a, piv, row_max, d) : R(0);
    r.rcond = std::min(r.rcond, rcond);
    if (!(rcond > min_rcond)) {
      r = _fail(r, rcond == rcond ? _kStatusSingular : _kStatusNonFinite, k);
      return false;
    }
    return true;
  }

  // Calls solve(size, k, a, piv) for each block k, in solve order or (kReverse) backwards,
  // with a and piv its factors and size its std::integral_constant size; stops at the first
  // block that fails to factor or whose solve returns false (a non-finite solution: status 3).
  template <class S, bool kReverse, class T, class R, class F>
  static BlockReport<R> _each_factored_block(const T* jac, const BasicBlockOptions<R>& o,
                                             F&& solve) noexcept {
    BlockReport<R> r;
    bool ok = true;
    for (int n = 0; ok && n < S::num_blocks; ++n) {
      const int k = kReverse ? S::num_blocks - 1 - n : n;
      _with_block_size<S>(S::block_begin[k + 1] - S::block_begin[k], [&](auto size) {
        constexpr int K = decltype(size)::value;
        T a[K * K];
        int piv[K];
        if (!(ok = _block_factor<S, K>(k, jac, a, piv, r, o.min_rcond))) return;
        if (!(ok = solve(size, k, a, piv))) r = _fail(r, _kStatusNonFinite, k);
      });
    }
    return r;
  }

  // Phi_q X = B: x and b hold m columns (column j at x + j * nq, b + j * nq; x must not
  // overlap b). Blocks in solve order; row r of block k subtracts its entries in earlier
  // blocks' coordinates, which are solved by then. A non-finite right-hand side or entry
  // outside the block shows only in the block's solution, which is checked.
  template <class S, class T, class R>
  static BlockReport<R> _block_forward(const T* jac, const T* b, T* x, int m,
                                       const BasicBlockOptions<R>& o) noexcept {
    return _each_factored_block<S, false>(
        jac, o, [&](auto size, int k, const T* a, const int* piv) {
          return _forward_block<S, decltype(size)::value>(k, jac, a, piv, b, x, m);
        });
  }
  // Block k (K x K, factors a, piv) of Phi_q X = B for m columns, earlier blocks solved.
  // kCheck false: no check that they are finite (a caller that checks what it computes from
  // them, which any non-finite value reaches).
  template <class S, int K, bool kCheck = true, class Index, class T>
  static bool _forward_block(Index k, const T* jac, const T* a, const int* piv, const T* b, T* x,
                             int m) noexcept {
    const int b0 = S::block_begin[k];
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
      if (kCheck && !_all_finite<K>(v)) return false;
      for (int j = 0; j < K; ++j) xc[S::block_cols[b0 + j]] = v[j];
    }
    return true;
  }

  // Several solves at one Phi_q with each block factored once: _block_factor_all keeps every
  // block's factors (block k's K x K at a + S::block_factor_begin[k], its pivots at piv +
  // S::block_begin[k]), checked as _block_forward checks them; then _block_forward_factored and
  // _block_transposed_factored give _block_forward's and _block_transposed's numbers bit for
  // bit. False from those: a solution that is not finite (kCheck false: not checked).
  template <class S, class T, class R>
  static BlockReport<R> _block_factor_all(const T* jac, T* a, int* piv,
                                          const BasicBlockOptions<R>& o) noexcept {
    BlockReport<R> r;
    _each_block_unrolled<S>([&](auto k, auto size) {
      return _block_factor<S, decltype(size)::value>(k, jac, a + S::block_factor_begin[k],
                                                     piv + S::block_begin[k], r, o.min_rcond);
    });
    return r;
  }
  template <class S, bool kCheck = true, class T>
  static bool _block_forward_factored(const T* jac, const T* a, const int* piv, const T* b, T* x,
                                      int m) noexcept {
    return _each_block_unrolled<S>([&](auto k, auto size) {
      return _forward_block<S, decltype(size)::value, kCheck>(k, jac, a + S::block_factor_begin[k],
                                                              piv + S::block_begin[k], b, x, m);
    });
  }
  template <class S, bool kCheck = true, class T>
  static bool _block_transposed_factored(const T* jac, const T* a, const int* piv, T* b, T* y,
                                         int m) noexcept {
    return _each_block_unrolled<S, true>([&](auto k, auto size) {
      for (int col = 0; col < m; ++col)
        if (!_transposed_block<S, decltype(size)::value, kCheck>(
                k, jac, a + S::block_factor_begin[k], piv + S::block_begin[k], b + col * S::nq,
                y + col * S::nq))
          return false;
      return true;
    });
  }

  // y of `row` is v: recorded, and subtracted from the equations of the coordinates the row
  // reads outside block `own` (-1: every coordinate, the row's own block's too).
  template <class S, class T>
  static void _transposed_row(int row, const T& v, int own, const T* jac, T* bc, T* yc) noexcept {
    yc[row] = v;
    for (int e = S::jac_row_begin[row]; e < S::jac_row_begin[row + 1]; ++e) {
      const int c = S::jac_cols[e];
      if (S::coordinate_block[c] != own) bc[c] -= jac[e] * v;
    }
  }
  // Block k of Phi_q^T y = b with its factors a, piv (K x K: its rows by its coordinates): bc
  // holds the equations of the coordinates (those of later blocks' rows subtracted), yc
  // receives its rows' y. False when they are not finite.
  template <class S, int K, bool kCheck = true, class Index, class T>
  static bool _transposed_block(Index k, const T* jac, const T* a, const int* piv, T* bc,
                                T* yc) noexcept {
    const int b0 = S::block_begin[k];
    T v[K];
    for (int j = 0; j < K; ++j) v[j] = bc[S::block_cols[b0 + j]];
    _lu_solve_transposed<K>(a, piv, v);
    if (kCheck && !_all_finite<K>(v)) return false;
    for (int i = 0; i < K; ++i) _transposed_row<S>(S::block_rows[b0 + i], v[i], k, jac, bc, yc);
    return true;
  }

  // Phi_q^T Y = B: y (by row) and b (by coordinate) hold m columns as in _block_forward; b is
  // used as work space and left changed. Blocks in reverse order: block k's coordinates'
  // equations involve only its own and later blocks' rows, and once its rows' y are known
  // they are subtracted from the equations of earlier blocks' coordinates.
  template <class S, class T, class R>
  static BlockReport<R> _block_transposed(const T* jac, T* b, T* y, int m,
                                          const BasicBlockOptions<R>& o) noexcept {
    return _each_factored_block<S, true>(jac, o, [&](auto size, int k, const T* a, const int* piv) {
      constexpr int K = decltype(size)::value;
      for (int col = 0; col < m; ++col)
        if (!_transposed_block<S, K>(k, jac, a, piv, b + col * S::nq, y + col * S::nq))
          return false;
      return true;
    });
  }

  // The entry of Phi_q at (row, col), from the row's entries.
  template <class S, class T>
  static T _jac_entry(const T* jac, int row, int col) noexcept {
    for (int e = S::jac_row_begin[row]; e < S::jac_row_begin[row + 1]; ++e)
      if (S::jac_cols[e] == col) return jac[e];
    return T(0);
  }
  // A 1 x 1 block of Phi_q^T y = b: its coefficient, which is its factorization. Its
  // reciprocal first, as _lu_factor keeps it: the division then overlaps the blocks before
  // (it reads no y), and the solve, which waits for them, multiplies.
  template <class S, class T>
  static bool _transposed_coefficient(int k, const T* jac, T* bc, T* yc) noexcept {
    const int row = S::block_rows[S::block_begin[k]], col = S::block_cols[S::block_begin[k]];
    const T inv = T(1) / _jac_entry<S>(jac, row, col);
    const T v = bc[col] * inv;
    if (!_finite(_mag(v))) return false;
    _transposed_row<S>(row, v, k, jac, bc, yc);
    return true;
  }
  // A torn block of Phi_q^T y = b, the adjoint of the rate solve's: with A = [L B; C E] (the
  // assigned rows by the assigned coordinates, L lower triangular with constant diagonal, then
  // the tears; the residual rows below), D = -L^-1 B the assigned coordinates' sensitivities to
  // the tears and S = E + C D their Schur complement (factored in a, piv; M = 1: the divisor),
  // the residual rows' y solve S^T y_r = b_t + D^T b_a, and then the assigned rows' y follow
  // from L^T y_a = b_a - C^T y_r, last row first. Linear in the block's entries.
  template <class S, int M, class T>
  static bool _transposed_torn(int k, const T* jac, const T* a, const int* piv, const T* d, T* bc,
                               T* yc) noexcept {
    const int b0 = S::block_begin[k], n = S::block_begin[k + 1] - b0 - M;  // n assigned
    T g[M];
    for (int j = 0; j < M; ++j) g[j] = bc[S::tear_cols[b0 + n + j]];
    for (int i = 0; i < n; ++i) {
      const T x = bc[S::tear_cols[b0 + i]];
      for (int j = 0; j < M; ++j) g[j] += d[i * M + j] * x;
    }
    if constexpr (M == 1) {
      g[0] /= a[0];
    } else {
      _lu_solve_transposed<M>(a, piv, g);
    }
    if (!_all_finite<M>(g)) return false;
    for (int i = 0; i < M; ++i) _transposed_row<S>(S::tear_rows[b0 + n + i], g[i], -1, jac, bc, yc);
    for (int i = n - 1; i >= 0; --i) {
      const int row = S::tear_rows[b0 + i], col = S::tear_cols[b0 + i];
      const T inv = T(1) / _jac_entry<S>(jac, row, col);  // as in _transposed_coefficient
      const T v = bc[col] * inv;
      if (!_finite(_mag(v))) return false;
      _transposed_row<S>(row, v, -1, jac, bc, yc);
    }
    return true;
  }
  // Phi_q^T y = b (one column) with the factors a full step kept (S::StepFactors, filled by
  // solve_step at the same q and t): nothing is factored again but the blocks the step did not
  // keep (S::step_factored). The condition is the step's (f->rcond); without factors, or when
  // that condition is below options.min_rcond, every block is factored again and checked as in
  // _block_transposed.
  template <class S, class T, class R, class F>
  static BlockReport<R> _block_transposed_reusing(const T* jac, T* b, T* y, const F* f,
                                                  const BasicBlockOptions<R>& o) noexcept {
    if (!f || !(f->rcond > o.min_rcond)) return _block_transposed<S>(jac, b, y, 1, o);
    BlockReport<R> r;
    r.rcond = R(f->rcond);
    bool ok = true;
    for (int n = 0; ok && n < S::num_blocks; ++n) {
      const int k = S::num_blocks - 1 - n, size = S::block_begin[k + 1] - S::block_begin[k];
      const int m = S::block_tears[k];
      const T* a = f->a + S::factor_begin[k];
      const int* piv = f->piv + S::block_begin[k];
      if (m == 0 && size == 1) {
        ok = _transposed_coefficient<S>(k, jac, b, y);
      } else if (!S::step_factored[k]) {
        _with_block_size<S>(size, [&](auto s) {
          constexpr int K = decltype(s)::value;
          T a2[K * K];
          int piv2[K];
          if (!(ok = _block_factor<S, K>(k, jac, a2, piv2, r, o.min_rcond))) return;
          ok = _transposed_block<S, K>(k, jac, a2, piv2, b, y);
        });
        if (r.status != 0) return r;
      } else if (m > 0) {
        _with_block_size<S>(m, [&](auto s) {
          ok = _transposed_torn<S, decltype(s)::value>(k, jac, a, piv, f->d + S::tear_sens_begin[k],
                                                       b, y);
        });
      } else {
        _with_block_size<S>(size, [&](auto s) {
          ok = _transposed_block<S, decltype(s)::value>(k, jac, a, piv, b, y);
        });
      }
      if (!ok) r = _fail(r, _kStatusNonFinite, k);
    }
    return r;
  }
  // kinegen-kernel-end block_linear
};

}  // namespace kinegen::kernels
