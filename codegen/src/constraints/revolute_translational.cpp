// revolute_translational: a pin in a slot. Body j's point sj stays on the line through body
// i's point si along vi, (A_i vi)^perp . d_ij = 0; the bodies may turn.
#include "common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> revolute_translational_equations(const EquationContext& c) { return {c.perpendicular(c.d_ij())}; }

// A block sliding on a guide fixed in body i (a slot when i moves).
void revolute_translational_draw(const DrawContext& c, Sketch& sketch) {
  const TwoPoints p = draw_two_points(c, sketch);
  sketch.sliders.push_back({p.j, p.i.body, p.i.s, unit_direction(c, "vi")});
}

}  // namespace

extern const ConstraintKind kRevoluteTranslational = two_point_joint({
    .name = "revolute_translational",
    .joint = true,
    .driver = false,
    .keys = {{"vi", KeyKind::kDirection, true}},
    .rows = 1,
    .equations = revolute_translational_equations,
    .draw = revolute_translational_draw,
});

}  // namespace kinegen::codegen
