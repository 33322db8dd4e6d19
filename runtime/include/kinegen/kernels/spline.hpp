// Cubic spline evaluation (mechanism format 6.3, `table:` drivers): value and first two
// derivatives of the interpolating cubic, from the knots t, values y and second derivatives m
// that the generator fitted (not-a-knot, or periodic). A kernel: plain C++17, std only,
// templated on the scalar, allocation-free; the generator embeds this text in headers whose
// model has a table, with the knots as constant arrays, and the analysis calls it directly.
#pragma once

#include <cmath>
#include <limits>

namespace kinegen::kernels {

// f[0..2] = S(x), S'(x), S''(x) on the knot interval that holds the real part of x. Returns
// false (and leaves f alone) when x lies outside [t[0], t[n-1]] by more than a few ulps of the
// table's span: a table is never extrapolated. n >= 2; t strictly increasing.
template <class T, class K>
bool spline_eval(const K* t, const K* y, const K* m, int n, const T& x, T* f) noexcept {
  using std::real;
  using R = decltype(real(x));
  const R xr = real(x);
  const R t0 = R(t[0]), t1 = R(t[n - 1]);
  const R slack = R(8) * std::numeric_limits<R>::epsilon() *
                  (std::abs(t0) > std::abs(t1) ? std::abs(t0) : std::abs(t1));
  if (!(xr >= t0 - slack && xr <= t1 + slack)) return false;  // NaN included
  // The last knot <= xr, kept in [0, n - 2] so the ends use their own intervals.
  int lo = 0, hi = n - 1;
  while (hi - lo > 1) {
    const int mid = lo + (hi - lo) / 2;
    if (R(t[mid]) <= xr) lo = mid; else hi = mid;
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
bool spline_eval_periodic(const K* t, const K* y, const K* m, int n, K period, K rise,
                          const T& x, T* f) noexcept {
  using std::floor, std::real;
  using R = decltype(real(x));
  const R xr = real(x);
  if (!(xr - xr == R(0))) return false;  // not finite
  const R p = R(period);
  const R turns = floor(xr / p);
  T local = x - T(turns * p);
  if (real(local) < R(0)) local = T(R(0)) + (local - T(real(local)));  // rounding below 0
  if (real(local) > p) local = T(p) + (local - T(real(local)));
  if (!spline_eval(t, y, m, n, local, f)) return false;
  f[0] += T(R(rise)) * x / T(p);
  f[1] += T(R(rise) / p);
  return true;
}

}  // namespace kinegen::kernels
