// Drivers in pieces and periodic laws: the choice of a piece by t and the whole
// periods in t. Both decide on the real part of their argument, so that the complex
// step still works. See report.hpp for how kernel files are used: the generator pastes this
// text into headers whose expressions select a piece or wrap a period, and the in-process
// evaluator calls it directly. It stands alone, like motion_law.hpp.
#pragma once

#include <cmath>
#include <type_traits>

namespace kinegen::kernels {

struct PiecewiseKernel {
  // kinegen-kernel-begin piecewise
  template <class T>
  static auto _piece_re(const T& x) noexcept {
    if constexpr (std::is_arithmetic_v<T>) {
      return x;
    } else {
      return x.real();
    }
  }
  // lo while the real part of c is below 0, else hi (a time at a boundary, c = t - until = 0,
  // takes the later piece). Both are computed; only the one chosen is returned.
  template <class T>
  static T _select(const T& c, const T& lo, const T& hi) noexcept {
    return _piece_re(c) < 0 ? lo : hi;
  }
  // floor of the real part of x, as a real scalar (whole periods: its derivative is 0).
  template <class T>
  static T _floor_re(const T& x) noexcept {
    using std::floor;
    return T(floor(_piece_re(x)));
  }
  // kinegen-kernel-end piecewise
};

template <class T>
T select_piece(const T& c, const T& lo, const T& hi) noexcept {
  return PiecewiseKernel::_select(c, lo, hi);
}
template <class T>
T floor_re(const T& x) noexcept {
  return PiecewiseKernel::_floor_re(x);
}

}  // namespace kinegen::kernels
