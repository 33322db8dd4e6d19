// Block-solver kernel: the Newton policy (convergence test with its rounding allowance, the
// residual recheck, the condition and branch checks), shared by the generated blocks and the
// runtime's dense loop. See report.hpp for how kernel files are used.
#pragma once

#include <algorithm>
#include <limits>

#include "kinegen/kernels/report.hpp"

namespace kinegen::kernels {

struct NewtonKernel : ReportKernel {
  // kinegen-kernel-begin newton
  // Rounding allowance, in units of the scalar's epsilon: no Newton step or residual can get
  // below the rounding of the terms it is made of (about 1 in scaled units: the mechanism's
  // lengths) and of the coordinate itself (an angle of 6e6 rad is known to 1e-9 in double).
  static constexpr int kRoundingUlps = 64;
  template <class R>
  static R _rounding(const R& magnitude) noexcept {
    return R(kRoundingUlps) * std::numeric_limits<R>::epsilon() * (R(1) + magnitude);
  }
  // The step criterion for one coordinate: dq is |Newton update| and q is |coordinate|, both
  // scaled (lengths divided by the length scale, angles in radians).
  template <class R>
  static bool _step_converged(const R& dq, const R& q, const R& tolerance) noexcept {
    return dq <= tolerance + _rounding(q);
  }
  // The largest v[i] / scale[i] (a block's scaled residual) with one division; NaN if any v is.
  template <int K, class R>
  static R _scaled_max(const R* v, const R* scale) noexcept {
    int m = 0;
    for (int i = 0; i < K; ++i) {
      if (!(v[i] == v[i])) return v[i];
      if (v[i] * scale[m] > v[m] * scale[i]) m = i;
    }
    return v[m] / scale[m];
  }
  // A block's condition within all of Phi_q: its rows equilibrated over their entries in
  // earlier blocks' columns too (coupled_max[i] >= row_max[i]: the largest scaled entry of the
  // whole row, row_max[i] that of the block's own). A row whose own entries are small beside
  // its couplings leaves the block nearly singular in the full matrix although the block alone
  // looks well conditioned (a 1 x 1 block always does); rcond times the smallest
  // row_max / coupled_max bounds the block's reciprocal condition there from below, within a
  // factor K.
  template <int K, class R>
  static R _coupled_rcond(const R& rcond, const R* row_max, const R* coupled_max) noexcept {
    R f = R(1);
    for (int i = 0; i < K; ++i)
      if (coupled_max[i] > row_max[i]) f = std::min(f, row_max[i] / coupled_max[i]);
    return rcond * f;
  }
  // A Newton block's end, after its last iteration: converged says whether the step criterion
  // held; residual is the largest scaled |Phi| of its rows at the final q; q_sum the sum of its
  // scaled |coordinates| (the residual's rounding grows with them); rcond and sign come from
  // the last factorization. Records the block in r; false (r.status and r.block set) when the
  // block failed. signs: nullptr, or the caller's entry per block (0: record the sign; else a
  // change of sign is a jump to another assembly branch).
  template <class R>
  static bool _newton_end(BlockReport<R>& r, int block, int iterations, bool converged,
                          const BasicBlockOptions<R>& o, const R& step, const R& residual,
                          const R& q_sum, const R& rcond, int sign, signed char* signs) noexcept {
    r.iterations = std::max(r.iterations, iterations);
    r.total_iterations += iterations;
    r.step = std::max(r.step, step);
    r.residual = std::max(r.residual, residual);
    r.rcond = std::min(r.rcond, rcond);
    const bool budget = o.fixed_iterations > 0 && iterations >= o.fixed_iterations;
    const bool small = residual <= o.residual_tolerance + _rounding(q_sum);
    if (small && (converged || budget) && rcond > o.min_rcond && !signs) return true;
    return _newton_verdict(r, block, budget, converged, small, o, residual, rcond, sign, signs);
  }
  // The rest of _newton_end, apart so that the common path stays small.
  template <class R>
  static bool _newton_verdict(BlockReport<R>& r, int block, bool budget, bool converged, bool small,
                              const BasicBlockOptions<R>& o, const R& residual, const R& rcond,
                              int sign, signed char* signs) noexcept {
    int status = 0;
    if (!_finite(residual)) {
      status = 3;
    } else if (!small) {
      status = budget ? 5 : converged ? 4 : 1;
    } else if (!budget && !converged) {
      status = 1;
    } else if (!(rcond > o.min_rcond)) {
      status = 2;
    } else if (signs) {
      if (signs[block] == 0)
        signs[block] = static_cast<signed char>(sign);
      else if (signs[block] != sign)
        status = 6;
    }
    if (status == 0) return true;
    r.status = status;
    r.block = block;
    return false;
  }
  // kinegen-kernel-end newton
};

}  // namespace kinegen::kernels
