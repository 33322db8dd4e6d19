// Block-solver kernel: the sin/cos cache that carries exact sin and cos of anchor angles from
// call to call. See report.hpp for how kernel files are used.
#pragma once

#include <cmath>
#include <limits>

#include "kinegen/kernels/rotation.hpp"

namespace kinegen::kernels {

struct TrigCacheKernel : RotationKernel {
  // kinegen-kernel-begin trig_cache
  // The cache: 3 values per cached coordinate, an anchor angle and its exact sin and cos. It
  // starts empty (NaN), and a slot is used only when its sin and cos lie on the unit circle, so
  // storage that was zero-filled or overwritten is recomputed, not trusted.
  template <class T, int N>
  struct BasicTrigCache {
    T values[N > 0 ? N : 1];
    BasicTrigCache() noexcept { clear(); }
    void clear() noexcept {
      for (T& v : values) v = T(std::numeric_limits<_real<T>>::quiet_NaN());
    }
    T* data() noexcept { return values; }
  };
  // sin and cos of a coordinate at the start of a solve. With a cache, a coordinate within
  // _rotate_limit of a valid anchor is rotated from it, so a step along a smooth motion costs
  // no sin or cos; otherwise they are evaluated and become the new anchor. Always one rotation
  // from exact values, so no error accumulates over many steps.
  template <class T>
  static void _trig(T& s, T& c, const T& angle, T* cache, int slot) noexcept {
    using R = _real<T>;
    if (cache) {
      const T* a = cache + 3 * slot;
      const T d = angle - a[0];
      if (_mag(d) <= _rotate_limit<R>() &&
          _mag(a[1] * a[1] + a[2] * a[2] - T(1)) <= R(16) * std::numeric_limits<R>::epsilon()) {
        _rotated(a[1], a[2], d, s, c);
        return;
      }
    }
    _trig_anchor(s, c, angle, cache ? cache + 3 * slot : nullptr);
  }
  // The rare path of _trig, on its own so that the common one stays small enough to inline.
  template <class T>
  static void _trig_anchor(T& s, T& c, const T& angle, T* a) noexcept {
    using std::cos, std::sin;
    s = sin(angle);
    c = cos(angle);
    if (a) {
      a[0] = angle;
      a[1] = s;
      a[2] = c;
    }
  }
  // kinegen-kernel-end trig_cache
};

}  // namespace kinegen::kernels
