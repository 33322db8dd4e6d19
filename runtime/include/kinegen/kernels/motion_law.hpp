// Motion laws: cycloidal, harmonic, 3-4-5 and 4-5-6-7 polynomial rises from 0 to 1, each its
// formula on [0, 1) and clamped outside it (0 for x < 0 and 1 for x >= 1, every derivative 0
// there): a value exactly at 0 or 1 is the limit from the right, as a driver's pieces take the
// later piece at a boundary, so that laws that join smoothly (a harmonic rise and its return)
// give the true f' and f'' at the joint. See report.hpp for how kernel files are used: the
// generator pastes this text into headers whose model calls a law, and the in-process
// evaluator calls it directly. It stands alone (no other kernel), since a header without a
// block solver may need it too.
#pragma once

#include <cmath>
#include <type_traits>

namespace kinegen::kernels {

enum MotionLaw : int { kCycloidal = 0, kHarmonic = 1, kPoly345 = 2, kPoly4567 = 3 };

struct MotionLawKernel {
  // kinegen-kernel-begin motion_law
  // The real part, on which the branch is chosen, so that the complex step still works.
  template <class T>
  static auto _law_re(const T& x) noexcept {
    if constexpr (std::is_arithmetic_v<T>) {
      return x;
    } else {
      return x.real();
    }
  }
  // d^order/dx^order of motion law `law` (0 cycloidal, 1 harmonic, 2 poly345, 3 poly4567) at x
  // (order >= 0): the formula on [0, 1), clamped outside it.
  template <class T>
  static T _motion_law(int law, int order, const T& x) noexcept {
    using std::cos, std::sin;
    using R = std::decay_t<decltype(_law_re(x))>;
    const R xr = _law_re(x);
    if (!(xr == xr)) return T(xr);  // NaN stays NaN
    if (xr < R(0)) return T(R(0));
    if (!(xr < R(1))) return T(order == 0 ? R(1) : R(0));
    const R pi = R(3.14159265358979323846264338327950288L);
    switch (law) {
      case 0: {
        // x - sin(2 pi x) / (2 pi): f' = 1 - cos(w), and for n >= 2 f^(n) = -(2 pi)^(n-1)
        // times the (n-1)-th derivative of cos at w = 2 pi x.
        const T w = T(2 * pi) * x;
        if (order == 0) return x - sin(w) / T(2 * pi);
        if (order == 1) {  // 1 - cos(w) without its cancellation near the ends
          const T half = sin(T(pi) * x);
          return T(2) * half * half;
        }
        R scale = R(1);
        for (int k = 1; k < order; ++k) scale *= 2 * pi;
        switch (order % 4) {
          case 1:
            return T(-scale) * cos(w);
          case 2:
            return T(scale) * sin(w);
          case 3:
            return T(scale) * cos(w);
          default:
            return T(-scale) * sin(w);
        }
      }
      case 1: {
        // (1 - cos(pi x)) / 2; its n-th derivative for n >= 1 is -(pi^n / 2) cos^(n)(pi x)
        const T w = T(pi) * x;
        if (order == 0) {  // (1 - cos(w)) / 2 without its cancellation near 0
          const T half = sin(T(R(0.5) * pi) * x);
          return half * half;
        }
        R scale = R(0.5);
        for (int k = 0; k < order; ++k) scale *= pi;
        switch (order % 4) {
          case 1:
            return T(scale) * sin(w);
          case 2:
            return T(scale) * cos(w);
          case 3:
            return T(-scale) * sin(w);
          default:
            return T(-scale) * cos(w);
        }
      }
      case 2:
      case 3: {
        // Both rise symmetrically, f(x) = 1 - f(1 - x), so the upper half is evaluated at
        // 1 - x (exact there): Horner then never cancels more than a digit, in float as well.
        if (order > 7) return T(0);
        const bool upper = xr > R(0.5);
        const T y = upper ? T(1) - x : x;
        // Coefficients of y^0..y^7, differentiated `order` times.
        R c[8] = {0, 0, 0, 0, 0, 0, 0, 0};
        if (law == 2) {
          c[3] = 10, c[4] = -15, c[5] = 6;
        } else {
          c[4] = 35, c[5] = -84, c[6] = 70, c[7] = -20;
        }
        for (int d = 0; d < order; ++d) {
          for (int k = 0; k < 7; ++k) c[k] = c[k + 1] * R(k + 1);
          c[7] = 0;
        }
        T v = T(c[7]);
        for (int k = 6; k >= 0; --k) v = v * y + T(c[k]);
        if (!upper) return v;
        if (order == 0) return T(1) - v;
        return order % 2 == 1 ? v : -v;  // d/dx = -d/dy, order times, on 1 - P(y)
      }
    }
    return T(R(0) / R(0));  // unknown law: NaN, never a plausible value
  }
  // kinegen-kernel-end motion_law
};

// d^order/dx^order of `law` at x (order >= 0): the formula on [0, 1), clamped outside it.
template <class T>
T motion_law(int law, int order, const T& x) noexcept {
  return MotionLawKernel::_motion_law(law, order, x);
}

}  // namespace kinegen::kernels
