// Point kinematics, once for every arithmetic (double in the analysis and the drawing, CLN
// numerics in the reference): the place, velocity and acceleration of a point fixed in a body.
#pragma once

#include <array>

namespace kinegen::codegen {

// The place of local offset (sx, sy) on a body at q = (x, y, phi): r + A(phi) s. c and s are
// cos(phi) and sin(phi), in the caller's arithmetic.
template <class T>
std::array<T, 2> point_position(const T* q, const T& c, const T& s, const T& sx, const T& sy) {
  return {q[0] + (c * sx - s * sy), q[1] + (s * sx + c * sy)};
}

// x, y, vx, vy, ax, ay of that point, with qd and qdd the body's velocities and accelerations:
// v = rd + w (A s)^perp, a = rdd + wd (A s)^perp - w^2 A s.
template <class T>
std::array<T, 6> point_kinematics(const T* q, const T* qd, const T* qdd, const T& c, const T& s,
                                  const T& sx, const T& sy) {
  const T ax = c * sx - s * sy, ay = s * sx + c * sy;  // A s
  const T &w = qd[2], &wd = qdd[2];
  return {q[0] + ax,
          q[1] + ay,
          qd[0] - w * ay,
          qd[1] + w * ax,
          qdd[0] - wd * ay - w * w * ax,
          qdd[1] + wd * ax - w * w * ay};
}

}  // namespace kinegen::codegen
