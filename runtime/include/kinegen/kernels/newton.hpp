// Block-solver kernel: the Newton policy, one set of decisions for every Newton loop in the
// project: the generated blocks (and the in-process block interpreter that mirrors them), the
// runtime's dense and sparse loop (solver.hpp) and the 40-digit CLN reference
// (codegen/src/analysis/reference.cpp). See report.hpp for how kernel files are used.
//
// The decisions, each a function below:
// - step criterion (_step_converged): the scaled update is at most tolerance + the rounding
//   allowance of the coordinate (_rounding);
// - residual recheck (_residual_converged): after the step criterion, the largest scaled |Phi|
//   is at most residual_tolerance + the rounding allowance of the terms it is made of;
// - linear convergence (_linear_step, _poorly_conditioned): Newton converges quadratically
//   onto a regular root, only linearly onto one where Phi_q is singular (a toggle: at a fold
//   each step halves the error, until the residual rounds to zero at an error of about
//   sqrt(eps), so the last step and the condition there tell little). A solve with at least
//   kLinearSteps steps that each shrank by less than kLinearRatio, ending at a condition
//   estimate worse than sqrt(min_rcond), is singular. The quadratic phase of a solve has at
//   most about log2(digits) = 6 steps, and a well conditioned root passes whatever the count;
//   only a root so ill conditioned that Newton needs many halvings to reach it (rcond below
//   sqrt(min_rcond): double 1.3e-6, above a fold's sqrt(eps) = 1.5e-8) counts as singular;
// - no progress (_stalled): the step stopped decreasing below a bound: the noise floor of the
//   arithmetic (used by the reference, whose tolerance is 10^5 ulps; the double paths' rounding
//   allowance already covers their floor);
// - iteration budget: max_iterations, or exactly fixed_iterations (block path);
// - the verdict (_newton_status): the status, in kinegen::Status order;
// - damping (_accept_step): the dense and sparse loop halve a step that makes the residual
//   grow; the block path does not damp (its blocks are small and start from the predictor;
//   a line search would cost a residual evaluation per iteration and, being data dependent,
//   a second code path that the interpreter would have to mirror bit for bit).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "kinegen/kernels/report.hpp"

namespace kinegen::kernels {

struct NewtonKernel : ReportKernel {
  // kinegen-kernel-begin newton
  // Rounding allowance, in units of the scalar's epsilon (eps: std::numeric_limits, or the
  // reference's 10^-digits): no Newton step or residual can get below the rounding of the
  // terms it is made of (about 1 in scaled units: the mechanism's lengths) and of the
  // coordinate itself (an angle of 6e6 rad is known to 1e-9 in double).
  static constexpr int kRoundingUlps = 64;
  template <class R>
  static R _rounding(const R& magnitude,
                     const R& eps = std::numeric_limits<R>::epsilon()) noexcept {
    return R(kRoundingUlps) * eps * (R(1) + magnitude);
  }
  // The step criterion for one coordinate: dq is |Newton update| and q is |coordinate|, both
  // scaled (lengths divided by the length scale, angles in radians).
  template <class R>
  static bool _step_converged(const R& dq, const R& q, const R& tolerance,
                              const R& eps = std::numeric_limits<R>::epsilon()) noexcept {
    return dq <= tolerance + _rounding(q, eps);
  }
  // The residual recheck: residual is a largest scaled |Phi|, terms the scaled magnitude of
  // what its rows are made of (a block: the sum of its scaled |q|).
  template <class R>
  static bool _residual_converged(const R& residual, const R& terms, const R& tolerance,
                                  const R& eps = std::numeric_limits<R>::epsilon()) noexcept {
    return residual <= tolerance + _rounding(terms, eps);
  }
  // A linear step: more than 1 / kLinearRatio of the step before (previous: 0 when there was
  // none). A solve with kLinearSteps of them converged linearly.
  static constexpr int kLinearRatio = 4;
  static constexpr int kLinearSteps = 8;
  template <class R>
  static int _linear_step(const R& step, const R& previous) noexcept {
    return previous > R(0) && step * R(kLinearRatio) > previous;
  }
  // The condition below which a linearly converging solve counts as singular.
  template <class R>
  static bool _poorly_conditioned(const R& rcond, const R& min_rcond) noexcept {
    using std::sqrt;
    return !(rcond > sqrt(min_rcond));
  }
  // The verdict, in the order of kinegen::Status (0: converged). budget: a fixed iteration
  // budget ran out; converged: the step criterion held; small: the residual recheck held;
  // linear: the solve converged linearly (kLinearSteps); residual: the (scaled) residual, for
  // the finite check.
  template <class R>
  static int _newton_status(bool budget, bool converged, bool small, bool linear, const R& residual,
                            const R& rcond, const R& min_rcond) noexcept {
    using std::abs;
    if (!_finite(abs(residual))) return _kStatusNonFinite;
    // The iterations ran out: converging linearly onto a singular point, or not at all.
    if (!converged && !budget)
      return linear && _poorly_conditioned(rcond, min_rcond) ? _kStatusSingular
                                                             : _kStatusMaxIterations;
    if (!small) return budget ? _kStatusBudgetExhausted : _kStatusInconsistent;
    if (!(rcond > min_rcond)) return _kStatusSingular;
    if (linear && _poorly_conditioned(rcond, min_rcond)) return _kStatusSingular;
    return _kStatusConverged;
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
  // held; step is its last scaled step, linear_steps how many of its steps were linear
  // (_linear_step); residual is the largest scaled |Phi| of its rows at the final q; q_sum the sum
  // of its scaled |coordinates| (the residual's rounding grows with them); rcond and sign come from
  // the last factorization. Records the block in r; false (r.status and r.block set) when the
  // block failed. signs: nullptr, or the caller's entry per block (0: record the sign; else a
  // change of sign is a jump to another assembly branch).
  template <class R>
  static bool _newton_end(BlockReport<R>& r, int block, int iterations, bool converged,
                          const BasicBlockOptions<R>& o, const R& step, int linear_steps,
                          const R& residual, const R& q_sum, const R& rcond, int sign,
                          signed char* signs) noexcept {
    r.iterations = std::max(r.iterations, iterations);
    r.total_iterations += iterations;
    r.step = std::max(r.step, step);
    r.residual = std::max(r.residual, residual);
    r.rcond = std::min(r.rcond, rcond);
    const bool budget = o.fixed_iterations > 0 && iterations >= o.fixed_iterations;
    const bool small = _residual_converged(residual, q_sum, o.residual_tolerance);
    const bool linear = linear_steps >= kLinearSteps;
    if (small && (converged || budget) && rcond > o.min_rcond && !linear && !signs) return true;
    return _newton_verdict(
        r, block, _newton_status(budget, converged, small, linear, residual, rcond, o.min_rcond),
        sign, signs);
  }
  // The rest of _newton_end, apart so that the common path stays small: the branch check.
  template <class R>
  static bool _newton_verdict(BlockReport<R>& r, int block, int status, int sign,
                              signed char* signs) noexcept {
    if (status == 0 && signs) {
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

  // Not pasted into generated headers (their blocks neither damp nor test for stalling):

  // No progress: the step did not decrease (previous: 0 when there was none) and is below
  // bound, the noise floor of the arithmetic.
  template <class R>
  static bool _stalled(const R& step, const R& previous, const R& bound) noexcept {
    return previous > R(0) && step >= previous && step <= bound;
  }
  // Damping (backtracking): a trial step whose scaled residual norm (trial) is not above the
  // current one's (current) is accepted; else it is halved, at most max_halvings times, and
  // never once the current residual is at the rounding floor (1000 eps), where the norms are
  // noise. A non-finite trial norm is never accepted before the halvings run out.
  template <class R>
  static bool _accept_step(const R& trial, const R& current, int halvings, int max_halvings,
                           const R& eps = std::numeric_limits<R>::epsilon()) noexcept {
    return halvings >= max_halvings || (_finite(trial) && trial <= current) ||
           current <= R(1000) * eps;
  }
};

}  // namespace kinegen::kernels
