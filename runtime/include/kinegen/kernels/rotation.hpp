// Block-solver kernel: sin and cos rotated by a small angle, for Newton updates and cached
// angles. See report.hpp for how kernel files are used.
#pragma once

#include <cmath>

#include "kinegen/kernels/report.hpp"

namespace kinegen::kernels {

struct RotationKernel : ReportKernel {
  // kinegen-kernel-begin rotation
  // Rotations of sin and cos by a small angle d, so that a Newton update or the step from a
  // cached angle needs no new sin or cos: on |d| <= 1/32 the series below are exact to double
  // rounding (the first omitted terms are below 3e-18 relative), and Newton's updates, mostly
  // below 2^-14, take two terms (the next below 2e-19 relative).
  template <class R>
  static constexpr R _rotate_limit() noexcept {
    return R(1) / R(32);
  }
  template <class T>
  static void _rotated(const T& s0, const T& c0, const T& d, T& s, T& c) noexcept {
    using R = _real<T>;
    // Horner forms; the reciprocals are constants the compiler folds (no division at run time).
    const T d2 = d * d;
    T sd, cm;  // sin d and 1 - cos d
    if (_mag(d) <= R(1) / R(16384)) {
      sd = d * (T(1) - d2 * (T(1) / T(6)));
      cm = d2 * (T(1) / T(2)) * (T(1) - d2 * (T(1) / T(12)));
    } else {
      sd = d * (T(1) -
                d2 * (T(1) / T(6)) * (T(1) - d2 * (T(1) / T(20)) * (T(1) - d2 * (T(1) / T(42)))));
      cm = d2 * (T(1) / T(2)) *
           (T(1) -
            d2 * (T(1) / T(12)) * (T(1) - d2 * (T(1) / T(30)) * (T(1) - d2 * (T(1) / T(56)))));
    }
    s = s0 + (c0 * sd - s0 * cm);
    c = c0 - (s0 * sd + c0 * cm);
  }
  // sin and cos of an angle after a Newton update d (angle = the new value).
  template <class T>
  static void _rotate(T& s, T& c, const T& d, const T& angle) noexcept {
    if (_mag(d) <= _rotate_limit<_real<T>>()) {
      _rotated(T(s), T(c), d, s, c);
    } else {
      using std::cos, std::sin;
      s = sin(angle);
      c = cos(angle);
    }
  }
  // kinegen-kernel-end rotation
};

}  // namespace kinegen::kernels
