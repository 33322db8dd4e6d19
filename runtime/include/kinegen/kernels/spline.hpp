// Cubic spline evaluation (`table:` drivers): value and first two derivatives of
// the interpolating cubic, from the knots t, values y and second derivatives m that
// the generator fitted (not-a-knot, or periodic). A kernel (see report.hpp): plain C++17,
// std only, templated on the scalar, allocation-free; the generator pastes this text into
// headers whose model has a table, with the knots as constant arrays, and the analysis calls
// it directly. It stands alone, like motion_law.hpp.
#pragma once

#include <cmath>
#include <limits>
#include <type_traits>

namespace kinegen::kernels {

struct SplineKernel {
  // kinegen-kernel-begin spline
  // The real part: x itself for a real scalar; for a complex one, real() found by argument
  // lookup (so this header needs no <complex> of its own).
  template <class T>
  static auto _spline_re(const T& x) noexcept {
    if constexpr (std::is_arithmetic_v<T>) {
      return x;
    } else {
      return real(x);
    }
  }
  // f[0..2] = S(x), S'(x), S''(x) on the knot interval that holds the real part of x. Returns
  // false (and leaves f alone) when x lies outside [t[0], t[n-1]] by more than a few ulps of
  // the table's span: a table is never extrapolated. n >= 2; t strictly increasing.
  template <class T, class K>
  static bool _spline_eval(const K* t, const K* y, const K* m, int n, const T& x, T* f) noexcept {
    using R = decltype(_spline_re(x));
    using std::abs;
    const R xr = _spline_re(x);
    const R t0 = R(t[0]), t1 = R(t[n - 1]);
    const R slack =
        R(8) * std::numeric_limits<R>::epsilon() * (abs(t0) > abs(t1) ? abs(t0) : abs(t1));
    if (!(xr >= t0 - slack && xr <= t1 + slack)) return false;  // NaN included
    // The last knot <= xr, kept in [0, n - 2] so the ends use their own intervals.
    int lo = 0, hi = n - 1;
    while (hi - lo > 1) {
      const int mid = lo + (hi - lo) / 2;
      if (R(t[mid]) <= xr) {
        lo = mid;
      } else {
        hi = mid;
      }
    }
    const T h = T(R(t[lo + 1]) - R(t[lo]));
    const T a = (T(R(t[lo + 1])) - x) / h;  // weight of the left knot
    const T b = T(1) - a;
    const T yl = T(R(y[lo])), yr = T(R(y[lo + 1])), ml = T(R(m[lo])), mr = T(R(m[lo + 1]));
    const T h2_6 = h * h / T(6);
    f[0] = a * yl + b * yr + ((a * a * a - a) * ml + (b * b * b - b) * mr) * h2_6;
    f[1] = (yr - yl) / h + ((T(1) - T(3) * a * a) * ml + (T(3) * b * b - T(1)) * mr) * h / T(6);
    f[2] = a * ml + b * mr;
    return true;
  }
  // A periodic table: the spline (t[0] = 0, t[n-1] = period, y the values less their linear
  // trend) repeats with the period, and the trend rise * x / period is added back, so every
  // period adds rise = f(period) - f(0). Defined for every finite x.
  template <class T, class K>
  static bool _spline_eval_periodic(const K* t, const K* y, const K* m, int n, K period, K rise,
                                    const T& x, T* f) noexcept {
    using std::floor;
    using R = decltype(_spline_re(x));
    const R xr = _spline_re(x);
    if (!(xr - xr == R(0))) return false;  // not finite
    const R p = R(period);
    const R turns = floor(xr / p);
    T local = x - T(turns * p);
    if (_spline_re(local) < R(0)) local = T(R(0)) + (local - T(_spline_re(local)));  // rounding
    if (_spline_re(local) > p) local = T(p) + (local - T(_spline_re(local)));
    if (!_spline_eval(t, y, m, n, local, f)) return false;
    f[0] += T(R(rise)) * x / T(p);
    f[1] += T(R(rise) / p);
    return true;
  }
  // The order-th derivative (0, 1 or 2) of a table's spline at x, or NaN outside a table
  // that does not repeat (period <= 0): a failure the solvers report as a non-finite value,
  // never an extrapolation. Nothing differentiates a driver's law more than twice.
  template <class T, class K>
  static T _table(const K* t, const K* y, const K* m, int n, K period, K rise, int order,
                  const T& x) noexcept {
    using R = decltype(_spline_re(x));
    T f[3];
    const bool ok = period > K(0) ? _spline_eval_periodic(t, y, m, n, period, rise, x, f)
                                  : _spline_eval(t, y, m, n, x, f);
    if (!ok || order < 0 || order > 2) return T(std::numeric_limits<R>::quiet_NaN());
    return f[order];
  }
  // kinegen-kernel-end spline
};

template <class T, class K>
bool spline_eval(const K* t, const K* y, const K* m, int n, const T& x, T* f) noexcept {
  return SplineKernel::_spline_eval(t, y, m, n, x, f);
}
template <class T, class K>
bool spline_eval_periodic(const K* t, const K* y, const K* m, int n, K period, K rise, const T& x,
                          T* f) noexcept {
  return SplineKernel::_spline_eval_periodic(t, y, m, n, period, rise, x, f);
}

}  // namespace kinegen::kernels
