// Block-solver kernel: the scalar's real type, magnitudes, defaults from
// std::numeric_limits, and the report and options of a block solve.
//
// Kernel files: the text between the kinegen-kernel markers is pasted unchanged into every
// generated header that calls it (inside the model struct, as static members); here it is
// compiled as the members of a struct, so that both read it the same way. Plain C++17, std
// only, templated on the scalar; nothing allocates.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>

namespace kinegen::kernels {

struct ReportKernel {
  // kinegen-kernel-begin report
  // Forces inlining where GCC or Clang read it: small helpers called in long runs (the reuse's
  // comparisons) and kernels whose callers' constant tables must fold into their loops.
#ifndef KINEGEN_ALWAYS_INLINE
#if defined(__GNUC__) || defined(__clang__)
#define KINEGEN_ALWAYS_INLINE [[gnu::always_inline]]
#else
#define KINEGEN_ALWAYS_INLINE
#endif
#endif
  // Keeps GCC's basic-block (SLP) vectorizer out of a function. In the Jacobians' long runs of
  // straight-line code it loads pairs of values just stored one by one, and such a load waits
  // for the stores (a failed store-to-load forwarding): the pendulum's took 28 ns, not 19, the
  // cart-pole's 113, not 88 (the press gains 8% from it). GCC then no longer inlines the
  // function into its callers. Define it empty before any kinegen header to keep the vectorizer.
#ifndef KINEGEN_NO_SLP
#if defined(__GNUC__) && !defined(__clang__) && defined(__has_cpp_attribute)
#if __has_cpp_attribute(gnu::optimize)
#define KINEGEN_NO_SLP [[gnu::optimize("no-tree-slp-vectorize")]]
#endif
#endif
#ifndef KINEGEN_NO_SLP
#define KINEGEN_NO_SLP
#endif
#endif
  // The most stack, in bytes, a generated function's work space may take; a larger one is the
  // caller's (dynamics_jacobians: JacobianWork's). Define it before any kinegen header (0: the
  // caller's always).
#ifndef KINEGEN_STACK_WORK_BYTES
#define KINEGEN_STACK_WORK_BYTES 4096
#endif
  // The real type of a scalar: T itself, or the value_type of std::complex<T>.
  template <class T, class = void>
  struct _RealOf {
    using type = T;
  };
  template <class T>
  struct _RealOf<T, std::void_t<typename T::value_type>> {
    using type = typename T::value_type;
  };
  template <class T>
  using _real = typename _RealOf<T>::type;
  // T, in a parameter that takes no part in deducing T: an optional output there accepts a
  // literal nullptr (std::type_identity_t, which C++17 lacks).
  template <class T>
  struct _Given {
    using type = T;
  };
  template <class T>
  using _given = typename _Given<T>::type;

  template <class T>
  static _real<T> _mag(const T& x) noexcept {
    using std::abs;
    return abs(x);
  }
  template <class T>
  static _real<T> _re(const T& x) noexcept {
    if constexpr (std::is_same_v<T, _real<T>>) {
      return x;
    } else {
      return x.real();
    }
  }
  // Whether a magnitude (|x|, never negative) is finite: false for infinity and NaN. (Types
  // without numeric_limits, as CLN's arbitrary-precision numbers: only NaN could fail.)
  template <class R>
  static bool _finite(const R& magnitude) noexcept {
    if constexpr (std::numeric_limits<R>::is_specialized) {
      return magnitude <= std::numeric_limits<R>::max();
    } else {
      return magnitude == magnitude;
    }
  }
  template <int N, class T>
  static bool _all_finite(const T* v) noexcept {
    bool ok = true;
    for (int k = 0; k < N; ++k) ok &= _finite(_mag(v[k]));  // no branch per value
    return ok;
  }
  // 2^-(num * digits / den) for the scalar's mantissa digits: tolerances that follow the
  // scalar's precision (double: 53 digits, float: 24).
  template <class R>
  static constexpr R _precision_power(int num, int den) noexcept {
    R x = R(1);
    for (int k = 0; k < num * std::numeric_limits<R>::digits / den; ++k) x /= R(2);
    return x;
  }

  // BlockReport::status values by name (kinegen::Status has the same order).
  static constexpr int _kStatusConverged = 0, _kStatusMaxIterations = 1, _kStatusSingular = 2,
                       _kStatusNonFinite = 3, _kStatusInconsistent = 4, _kStatusBudgetExhausted = 5,
                       _kStatusBranchJump = 6, _kStatusTooFar = 7;
  // A first solve's continuation takes at most this many steps (else _kStatusTooFar).
  static constexpr int _kMaxContinuationSteps = 100000;
  // Outcome of a block solve. status: the order of kinegen::Status (0 converged, 1 Newton did
  // not converge within max_iterations, 2 a block's Jacobian is singular, 3 a non-finite value
  // appeared, 4 Newton's step vanished but the residual did not, 5 a fixed iteration budget ran
  // out with the residual above tolerance, 6 a block's determinant changed sign: another
  // assembly branch, 7 a first solve's continuation would take too many steps).
  template <class R>
  struct BlockReport {
    int status = 0;
    int block = -1;            // the block that failed
    int iterations = 0;        // largest Newton iteration count of any block
    int total_iterations = 0;  // Newton iterations summed over the blocks
    R step = 0;                // largest last scaled Newton step
    R residual = 0;            // largest scaled |Phi| of a Newton block at its end
    R rcond = 1;               // smallest estimated reciprocal condition of a Newton block
  };
  // Tolerances in the scalar's real type R, with defaults from its precision.
  template <class R>
  struct BasicBlockOptions {
    // Newton on a block stops when its step, lengths divided by length_scale and angles in
    // radians, is at most this plus the rounding allowance (newton kernel); or after exactly
    // fixed_iterations when that is positive. 2^-(5 digits / 8): double 1.2e-10, float 3.1e-5.
    R tolerance = _precision_power<R>(5, 8);
    int max_iterations = 30;  // per block
    int fixed_iterations = 0;
    // A block's Jacobian counts as singular when its smallest LU pivot is below this times
    // its largest (1 x 1 blocks: when it is zero). 2^9 eps: double 1.1e-13, float 6.1e-5.
    R singular_pivot_ratio = R(512) * std::numeric_limits<R>::epsilon();
    // After the last iteration every scaled |Phi| of the block must be at most this (plus the
    // rounding allowance). 2^-(digits / 2): double 1.5e-8, float 2.4e-4.
    R residual_tolerance = _precision_power<R>(1, 2);
    // A block whose estimated reciprocal condition is at most this counts as singular.
    // 2^-(3 digits / 4): double 1.8e-12, float 3.8e-6.
    R min_rcond = _precision_power<R>(3, 4);
  };
  // The options of earlier headers (double); any BasicBlockOptions<U> works with any scalar.
  using BlockOptions = BasicBlockOptions<double>;
  template <class R, class U>
  static BasicBlockOptions<R> _options_as(const BasicBlockOptions<U>& u) noexcept {
    BasicBlockOptions<R> o;
    o.tolerance = R(u.tolerance);
    o.max_iterations = u.max_iterations;
    o.fixed_iterations = u.fixed_iterations;
    o.singular_pivot_ratio = R(u.singular_pivot_ratio);
    o.residual_tolerance = R(u.residual_tolerance);
    o.min_rcond = R(u.min_rcond);
    return o;
  }
  // Whether a and b are the same number, -0.0 and 0.0 apart: float and double by their bits
  // (one integer comparison; a NaN matches only the same NaN), other floating types by value
  // and sign (a NaN never matches), a complex number's parts with ==.
  template <class X>
  KINEGEN_ALWAYS_INLINE static bool _same_bits(const X& a, const X& b) noexcept {
    if constexpr (std::is_same_v<X, double> && sizeof(double) == sizeof(unsigned long long)) {
      unsigned long long u, v;
      std::memcpy(&u, &a, sizeof u);
      std::memcpy(&v, &b, sizeof v);
      return u == v;
    } else if constexpr (std::is_same_v<X, float> && sizeof(float) == sizeof(unsigned)) {
      unsigned u, v;
      std::memcpy(&u, &a, sizeof u);
      std::memcpy(&v, &b, sizeof v);
      return u == v;
    } else if constexpr (std::is_floating_point_v<X>) {
      return a == b && std::signbit(a) == std::signbit(b);
    } else {
      return a == b;
    }
  }
  template <class R>
  static bool _same_options(const BasicBlockOptions<R>& a, const BasicBlockOptions<R>& b) noexcept {
    return a.tolerance == b.tolerance && a.max_iterations == b.max_iterations &&
           a.fixed_iterations == b.fixed_iterations &&
           a.singular_pivot_ratio == b.singular_pivot_ratio &&
           a.residual_tolerance == b.residual_tolerance && a.min_rcond == b.min_rcond;
  }

  template <class R>
  static BlockReport<R> _fail(BlockReport<R> r, int status, int block,
                              int iterations = 0) noexcept {
    r.status = status;
    r.block = block;
    r.iterations = std::max(r.iterations, iterations);
    r.total_iterations += iterations;
    return r;
  }
  // kinegen-kernel-end report
};

}  // namespace kinegen::kernels
