// A dense LU with partial pivoting on CLN numbers, for the high-precision references
// (reference.cpp's forces, reference_dynamics.cpp's motion). One implementation: both solve
// with it. Private to the analysis stage.
#pragma once

#include <ginac/ginac.h>

#include <algorithm>
#include <utility>
#include <vector>

namespace kinegen::codegen::analysis_detail {

// n is small (3 per body): dense, row-major, and exact zeros skipped.
class NumericLu {
 public:
  using Vector = std::vector<GiNaC::numeric>;

  // false when a pivot is at most `ratio` times the largest entry of the matrix.
  bool factor(std::vector<GiNaC::numeric> a, int n, const GiNaC::numeric& ratio) {
    a_ = std::move(a);
    n_ = n;
    perm_.resize(n);
    GiNaC::numeric largest = 0;
    for (const auto& v : a_) largest = std::max(largest, GiNaC::abs(v));
    if (largest.is_zero()) return false;
    for (int k = 0; k < n; ++k) perm_[k] = k;
    for (int k = 0; k < n; ++k) {
      int p = k;
      for (int r = k + 1; r < n; ++r)
        if (GiNaC::abs(at(r, k)) > GiNaC::abs(at(p, k))) p = r;
      if (GiNaC::abs(at(p, k)) <= ratio * largest) return false;
      if (p != k) {
        for (int c = 0; c < n; ++c) std::swap(at(p, c), at(k, c));
        std::swap(perm_[p], perm_[k]);
      }
      const GiNaC::numeric inv = GiNaC::numeric(1) / at(k, k);
      for (int r = k + 1; r < n; ++r) {
        if (at(r, k).is_zero()) continue;
        const GiNaC::numeric f = at(r, k) * inv;
        at(r, k) = f;
        for (int c = k + 1; c < n; ++c)
          if (!at(k, c).is_zero()) at(r, c) = at(r, c) - f * at(k, c);
      }
    }
    return true;
  }
  // A x = b.
  Vector solve(const Vector& b) const {
    Vector x(n_);
    for (int r = 0; r < n_; ++r) {
      GiNaC::numeric s = b[perm_[r]];
      for (int c = 0; c < r; ++c)
        if (!at(r, c).is_zero()) s = s - at(r, c) * x[c];
      x[r] = s;
    }
    for (int r = n_ - 1; r >= 0; --r) {
      GiNaC::numeric s = x[r];
      for (int c = r + 1; c < n_; ++c)
        if (!at(r, c).is_zero()) s = s - at(r, c) * x[c];
      x[r] = s / at(r, r);
    }
    return x;
  }
  // A^T x = b (P A = L U, so A^T = U^T L^T P): for Phi_q^T lambda = Q.
  Vector solve_transposed(const Vector& b) const {
    Vector y(n_), x(n_);
    for (int r = 0; r < n_; ++r) {
      GiNaC::numeric s = b[r];
      for (int c = 0; c < r; ++c)
        if (!at(c, r).is_zero()) s = s - at(c, r) * y[c];
      y[r] = s / at(r, r);
    }
    for (int r = n_ - 1; r >= 0; --r) {
      GiNaC::numeric s = y[r];
      for (int c = r + 1; c < n_; ++c)
        if (!at(c, r).is_zero()) s = s - at(c, r) * y[c];
      y[r] = s;
    }
    for (int r = 0; r < n_; ++r) x[perm_[r]] = y[r];
    return x;
  }

 private:
  GiNaC::numeric& at(int r, int c) { return a_[r * n_ + c]; }
  const GiNaC::numeric& at(int r, int c) const { return a_[r * n_ + c]; }
  std::vector<GiNaC::numeric> a_;
  std::vector<int> perm_;
  int n_ = 0;
};

}  // namespace kinegen::codegen::analysis_detail
