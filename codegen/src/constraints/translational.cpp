// translational: a slider without rotation. Body j's point sj stays on the line through body
// i's point si along vi, (A_i vi)^perp . d_ij = 0, and the relative angle stays at `angle`.
#include "common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> translational_equations(const EquationContext& c) {
  const auto d = c.d_ij();
  return {c.perpendicular(d), c.frame_j().phi - c.frame_i().phi - c.value()};
}

// A block sliding on a guide fixed in body i (a slot when i moves).
void translational_draw(const DrawContext& c, Sketch& sketch) {
  const TwoPoints p = draw_two_points(c, sketch);
  sketch.sliders.push_back({p.j, p.i.body, p.i.s, unit_direction(c, "vi")});
}

std::string translational_row_name(const Constraint&, int component) {
  return component == 0 ? "normal offset" : "relative angle";
}

}  // namespace

extern const ConstraintKind kTranslational = two_point_joint({
    .name = "translational",
    .joint = true,
    .driver = false,
    .keys = {{"vi", KeyKind::kDirection, true}, {"angle", KeyKind::kValue, false}},
    .rows = 2,
    .equations = translational_equations,
    .draw = translational_draw,
    .row_name = translational_row_name,
});

}  // namespace kinegen::codegen
