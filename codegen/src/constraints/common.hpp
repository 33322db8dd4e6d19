// What the joints between two bodies share: the keys i and j (a body or ground) with a point
// on each, si on body i and sj on body j (default [0, 0]); the reaction reported at those
// points; and their drawing's landmarks. For the type files of this folder only.
#pragma once

#include <Eigen/Core>
#include <utility>
#include <vector>

#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

// `kind` with the keys i, j, si, sj before its own keys, and its reaction at si and sj.
inline ConstraintKind two_point_joint(ConstraintKind kind) {
  std::vector<KeySpec> keys = {{"i", KeyKind::kBodyOrGround, true},
                               {"j", KeyKind::kBodyOrGround, true},
                               {"si", KeyKind::kOffset, false},
                               {"sj", KeyKind::kOffset, false}};
  keys.insert(keys.end(), kind.keys.begin(), kind.keys.end());
  kind.keys = std::move(keys);
  kind.reaction_i = "si";
  kind.reaction_j = "sj";
  return kind;
}

// The points si on body i and sj on body j, in numbers.
struct TwoPoints {
  Attach i, j;
};

// The two points, each added as a landmark of its body's outline.
inline TwoPoints draw_two_points(const DrawContext& c, Sketch& sketch) {
  const Constraint& k = c.constraint;
  const TwoPoints p{{k.i, c.vector("si")}, {k.j, c.vector("sj")}};
  sketch.landmarks.push_back(p.i);
  sketch.landmarks.push_back(p.j);
  return p;
}

// A point on ground is drawn as a ground pivot.
inline void draw_ground_pivots(const TwoPoints& p, Sketch& sketch) {
  for (const Attach& a : {p.i, p.j})
    if (a.body == kGround) sketch.ground_pivots.push_back(a.s);
}

// A direction key as a unit vector (zero stays zero: the equations refuse it).
inline Eigen::Vector2d unit_direction(const DrawContext& c, const std::string& key) {
  Eigen::Vector2d v = c.vector(key);
  // stableNorm: [1e-300, 0] is a direction too (its squares underflow).
  if (const double n = v.stableNorm(); n > 0) v /= n;
  return v;
}

}  // namespace kinegen::codegen
