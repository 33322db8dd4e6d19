// What the spatial joint and driver types share (docs/format.md, Spatial mechanisms): vector
// algebra on 3-vectors of expressions, the keys i, j, si, sj, the unit axes with their normals
// f and g, and vectors "carried into body j at the q0 pose". For the spatial_*.cpp files of
// this folder only.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "common.hpp"  // two_point_joint
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/constraints/spatial_branch.hpp"

namespace kinegen::codegen::spatial {

using V3 = EquationContext::Vec3;
using GiNaC::ex;

inline ex dot(const V3& a, const V3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline V3 cross(const V3& a, const V3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline V3 scaled(const V3& a, const ex& k) { return {a[0] * k, a[1] * k, a[2] * k}; }
inline V3 sum(const V3& a, const V3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }

// A double as the exact binary fraction it is, so the equations stay exact expressions.
inline ex exact(double v) {
  if (v == 0 || !std::isfinite(v)) return 0;
  int e = 0;
  const double m = std::frexp(v, &e);
  const long long mantissa = static_cast<long long>(std::ldexp(m, 53));
  return GiNaC::numeric(mantissa) * GiNaC::pow(GiNaC::numeric(2), e - 53);
}
inline V3 exact(const Eigen::Vector3d& v) { return {exact(v[0]), exact(v[1]), exact(v[2])}; }

// `kind` with the keys i, j, si, sj before its own, reactions at si and sj, spatial.
inline ConstraintKind spatial_two_point(ConstraintKind kind) {
  kind = two_point_joint(std::move(kind));
  kind.space = KindSpace::kSpatial;
  return kind;
}

// A direction key's numbers (parameters substituted).
inline Eigen::Vector3d numbers(const EquationContext& c, const V3& v) {
  return {c.number(v[0]), c.number(v[1]), c.number(v[2])};
}

// An axis key normalized (exactly: a / |a|); a zero axis is an input error at the key.
inline V3 unit_axis(const EquationContext& c, const std::string& key) {
  const V3 a = c.vector3(key);
  if (numbers(c, a).norm() < 1e-12) c.fail(key, "the axis must not be zero");
  return scaled(a, 1 / GiNaC::sqrt(dot(a, a)));
}

// f = unit(e_k x a) with e_k the coordinate axis of a's smallest |component| (the first on
// ties), g = a x f: (f, g, a) right-handed and orthonormal, a a unit axis.
struct Normals {
  V3 f, g;
};
inline Normals normals(const EquationContext& c, const V3& a) {
  const Eigen::Vector3d n = numbers(c, a).cwiseAbs();
  int k = 0;
  for (int m = 1; m < 3; ++m)
    if (n[m] < n[k]) k = m;
  V3 e{0, 0, 0};
  e[k] = 1;
  const V3 f0 = cross(e, a);
  const V3 f = scaled(f0, 1 / GiNaC::sqrt(dot(f0, f0)));
  return {f, cross(a, f)};
}

// The rotation taking body j's frame at the q0 pose to its frame after the smallest rotation
// that makes A_j axis_j parallel (or antiparallel, whichever is nearer) to A_i axis_i; a vector
// carried into j is (this)^T v_global. Without axes, A_j at the q0 pose.
inline Eigen::Matrix3d aligned_rotation0(const EquationContext& c, const Eigen::Vector3d& axis_i,
                                         const Eigen::Vector3d& axis_j) {
  const int i = c.constraint().i, j = c.constraint().j;
  const Eigen::Vector3d ai = (c.rotation0(i) * axis_i).normalized();
  const Eigen::Vector3d aj = (c.rotation0(j) * axis_j).normalized();
  const Eigen::Vector3d target = ai.dot(aj) >= 0 ? ai : Eigen::Vector3d(-ai);
  const Eigen::Quaterniond turn = Eigen::Quaterniond::FromTwoVectors(aj, target);
  return turn.toRotationMatrix() * c.rotation0(j);
}

// A global vector at the q0 pose carried into body j (rotation from aligned_rotation0).
inline Eigen::Vector3d carried(const Eigen::Matrix3d& rotation_j, const Eigen::Vector3d& v) {
  return rotation_j.transpose() * v;
}

// A(p) v of a body's frame.
inline V3 global(const EquationContext& c, int body, const V3& v) {
  return EquationContext::rotate3(c.frame3(body).p, v);
}

inline std::string xyz_row(const Constraint&, int component) {
  return component == 0 ? "x-component" : component == 1 ? "y-component" : "z-component";
}

// The branch of a joint whose axes are held parallel (revolute, cylindrical, translational):
// they point the same way, not opposite.
inline std::pair<GiNaC::ex, std::string> axes_aligned(const EquationContext& c) {
  const auto& k = c.constraint();
  return {dot(global(c, k.i, unit_axis(c, "axis_i")), global(c, k.j, unit_axis(c, "axis_j"))),
          "axis_i . axis_j"};
}

}  // namespace kinegen::codegen::spatial
