// fixed: a weld. Point si of body i and point sj of body j coincide, d_ij = 0, and the
// relative angle stays at `angle` (default 0): body j moves as part of body i.
#include "kinegen/codegen/constraints.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> equations(const EquationContext& c) {
  const auto d = c.d_ij();
  return {d.first, d.second, c.frame_j().phi - c.frame_i().phi - c.value()};
}

// Both outlines reach the common point, which is marked as a weld.
void draw(const DrawContext& c, Sketch& sketch) {
  const Constraint& k = c.constraint;
  const Eigen::Vector2d si = c.vector("si"), sj = c.vector("sj");
  sketch.landmarks.push_back({k.i, si});
  sketch.landmarks.push_back({k.j, sj});
  sketch.welds.push_back({k.i, si});
  if (k.i == kGround) sketch.ground_pivots.push_back(si);
  if (k.j == kGround) sketch.ground_pivots.push_back(sj);
}

std::string row_name(const Constraint&, int component) {
  return component == 0 ? "x-component" : component == 1 ? "y-component" : "relative angle";
}

}  // namespace

extern const ConstraintKind kFixed{
    .name = "fixed",
    .joint = true,
    .driver = false,
    .keys = {{"i", KeyKind::kBodyOrGround, true},
             {"j", KeyKind::kBodyOrGround, true},
             {"si", KeyKind::kOffset, false},
             {"sj", KeyKind::kOffset, false},
             {"angle", KeyKind::kValue, false}},
    .rows = 3,
    .equations = equations,
    .draw = draw,
    .row_name = row_name,
    .reaction_i = "si",
    .reaction_j = "sj",
};

}  // namespace kinegen::codegen
