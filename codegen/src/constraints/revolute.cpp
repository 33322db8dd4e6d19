// revolute: a pin. Point si of body i and point sj of body j coincide: d_ij = 0.
#include "common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> revolute_equations(const EquationContext& c) {
  const auto d = c.d_ij();
  return {d.first, d.second};
}

void revolute_draw(const DrawContext& c, Sketch& sketch) {
  const TwoPoints p = draw_two_points(c, sketch);
  sketch.pins.push_back(p.i);
  draw_ground_pivots(p, sketch);
}

std::string revolute_row_name(const Constraint&, int component) {
  return component == 0 ? "x-component" : "y-component";
}

}  // namespace

extern const ConstraintKind kRevolute = two_point_joint({
    .name = "revolute",
    .joint = true,
    .driver = false,
    .keys = {},  // i, j, si, sj only
    .rows = 2,
    .equations = revolute_equations,
    .draw = revolute_draw,
    .row_name = revolute_row_name,
});

}  // namespace kinegen::codegen
