// The one list of joint and driver types. A new type: its file in this folder (CMake globs
// them) and one line in each of the two lists below.
#include "kinegen/codegen/constraints/registry.hpp"

#include "kinegen/codegen/constraints/spatial_branch.hpp"

namespace kinegen::codegen {

extern const ConstraintKind kRevolute, kTranslational, kDistance, kRevoluteTranslational,
    kAbsoluteX, kAbsoluteY, kAbsoluteAngle, kRelativeAngle, kExpression, kFixed, kGear, kRackPinion,
    kPointFollower, kCamFollower;
// Spatial files' types (docs/format.md, Spatial mechanisms).
extern const ConstraintKind kSpatialDp1, kSpatialDp2, kSpatialD, kSpatialCd, kSpatialSpherical,
    kSpatialUniversal, kSpatialRevolute, kSpatialCylindrical, kSpatialTranslational,
    kSpatialDistance, kSpatialFixed, kSpatialRevoluteAngle, kSpatialTranslation,
    kSpatialAbsoluteX, kSpatialAbsoluteY, kSpatialAbsoluteZ, kEulerNormalization;
extern const SpatialBranch kSpatialRevoluteBranch, kSpatialCylindricalBranch,
    kSpatialTranslationalBranch, kSpatialRevoluteAngleBranch, kSpatialFixedBranch;

BranchConditions branch_conditions(const EquationContext& context) {
  for (const SpatialBranch* b :
       {&kSpatialRevoluteBranch, &kSpatialCylindricalBranch, &kSpatialTranslationalBranch,
        &kSpatialRevoluteAngleBranch, &kSpatialFixedBranch})
    if (b->kind == context.constraint().kind) return b->conditions(context);
  return {};
}

const std::vector<const ConstraintKind*>& constraint_kinds() {
  static const std::vector<const ConstraintKind*> kKinds = {
      &kRevolute,   &kTranslational, &kDistance,      &kRevoluteTranslational,
      &kAbsoluteX,  &kAbsoluteY,     &kAbsoluteAngle, &kRelativeAngle,
      &kExpression, &kFixed,         &kGear,          &kRackPinion,
      &kPointFollower, &kCamFollower,
      &kSpatialDp1, &kSpatialDp2, &kSpatialD, &kSpatialCd, &kSpatialSpherical,
      &kSpatialUniversal, &kSpatialRevolute, &kSpatialCylindrical, &kSpatialTranslational,
      &kSpatialDistance, &kSpatialFixed, &kSpatialRevoluteAngle, &kSpatialTranslation,
      &kSpatialAbsoluteX, &kSpatialAbsoluteY, &kSpatialAbsoluteZ, &kEulerNormalization,
  };
  return kKinds;
}

const ConstraintKind* find_constraint_kind(const std::string& name, bool spatial) {
  for (const ConstraintKind* k : constraint_kinds())
    if (name == k->name && k->in_space(spatial)) return k;
  return nullptr;
}

std::vector<std::pair<int, const Vec2*>> offsets(const Constraint& c) {
  std::vector<std::pair<int, const Vec2*>> out;
  for (const KeySpec& k : c.kind->keys)
    if (k.kind == KeyKind::kOffset)
      out.emplace_back(std::string(k.name) == "sj" ? c.j : c.i, &c.vector(k.name));
  return out;
}

Sketch::Curve DrawContext::sampled_curve(int body, const std::string& key,
                                         const std::string& coordinate_key) const {
  Sketch::Curve curve{body, {}};
  if (!curve_point || !curve_range) return curve;
  const auto [from, to] = curve_range(constraint.coordinates.at(coordinate_key));
  constexpr int kSamples = 96;
  for (int k = 0; k <= kSamples; ++k)
    curve.points.push_back(curve_point(key, from + (to - from) * k / kSamples));
  return curve;
}

Vec2 reaction_point(const Constraint& c, const char* key) {
  if (key) return c.vector(key);
  const Expr zero{"0", c.loc};
  return {zero, zero};
}

}  // namespace kinegen::codegen
