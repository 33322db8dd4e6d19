// The one list of joint and driver types. A new type: its file in this folder (CMake globs
// them) and one line in each of the two lists below.
#include "kinegen/codegen/constraints.hpp"

namespace kinegen::codegen {

extern const ConstraintKind kRevolute, kTranslational, kDistance, kRevoluteTranslational,
    kAbsoluteX, kAbsoluteY, kAbsoluteAngle, kRelativeAngle, kExpression, kFixed, kGear, kRackPinion;

const std::vector<const ConstraintKind*>& constraint_kinds() {
  static const std::vector<const ConstraintKind*> kKinds = {
      &kRevolute,   &kTranslational, &kDistance,      &kRevoluteTranslational,
      &kAbsoluteX,  &kAbsoluteY,     &kAbsoluteAngle, &kRelativeAngle,
      &kExpression, &kFixed,         &kGear,          &kRackPinion,
  };
  return kKinds;
}

const ConstraintKind* find_constraint_kind(const std::string& name) {
  for (const ConstraintKind* k : constraint_kinds())
    if (name == k->name) return k;
  return nullptr;
}

std::vector<std::pair<int, const Vec2*>> offsets(const Constraint& c) {
  std::vector<std::pair<int, const Vec2*>> out;
  for (const KeySpec& k : c.kind->keys)
    if (k.kind == KeyKind::kOffset)
      out.emplace_back(std::string(k.name) == "sj" ? c.j : c.i, &c.vector(k.name));
  return out;
}

Vec2 reaction_point(const Constraint& c, const char* key) {
  if (key) return c.vector(key);
  const Expr zero{"0", c.loc};
  return {zero, zero};
}

}  // namespace kinegen::codegen
