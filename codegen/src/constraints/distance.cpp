// distance: points si of body i and sj of body j stay `length` apart (a driver: f(t) apart),
// |d_ij|^2 - length^2 = 0.
#include "common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> distance_equations(const EquationContext& c) {
  const auto d = c.d_ij();
  return {GiNaC::pow(d.first, 2) + GiNaC::pow(d.second, 2) - GiNaC::pow(c.value(), 2)};
}

// A strut between the two points.
void distance_draw(const DrawContext& c, Sketch& sketch) {
  const TwoPoints p = draw_two_points(c, sketch);
  sketch.struts.push_back({p.i, p.j});
}

}  // namespace

extern const ConstraintKind kDistance = two_point_joint({
    .name = "distance",
    .joint = true,
    .driver = true,
    .keys = {{"length", KeyKind::kValue, true}},
    .rows = 1,
    .equations = distance_equations,
    .draw = distance_draw,
    .squared_distance = true,
});

}  // namespace kinegen::codegen
