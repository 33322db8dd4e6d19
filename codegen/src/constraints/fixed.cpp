// fixed: a weld. Point si of body i and point sj of body j coincide, d_ij = 0, and the
// relative angle stays at `angle` (default 0): body j moves as part of body i.
#include "common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> fixed_equations(const EquationContext& c) {
  const auto d = c.d_ij();
  return {d.first, d.second, c.frame_j().phi - c.frame_i().phi - c.value()};
}

// Both outlines reach the common point, which is marked as a weld.
void fixed_draw(const DrawContext& c, Sketch& sketch) {
  const TwoPoints p = draw_two_points(c, sketch);
  sketch.welds.push_back(p.i);
  draw_ground_pivots(p, sketch);
}

std::string fixed_row_name(const Constraint&, int component) {
  return component == 0 ? "x-component" : component == 1 ? "y-component" : "relative angle";
}

}  // namespace

extern const ConstraintKind kFixed = two_point_joint({
    .name = "fixed",
    .joint = true,
    .driver = false,
    .keys = {{"angle", KeyKind::kValue, false}},
    .rows = 3,
    .equations = fixed_equations,
    .draw = fixed_draw,
    .row_name = fixed_row_name,
});

}  // namespace kinegen::codegen
