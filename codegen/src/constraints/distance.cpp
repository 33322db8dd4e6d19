// distance: points si of body i and sj of body j stay `length` apart (a driver: f(t) apart),
// |d_ij|^2 - length^2 = 0.
#include "kinegen/codegen/constraints.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> equations(const EquationContext& c) {
  const auto d = c.d_ij();
  return {GiNaC::pow(d.first, 2) + GiNaC::pow(d.second, 2) - GiNaC::pow(c.value(), 2)};
}

// A strut between the two points.
void draw(const DrawContext& c, Sketch& sketch) {
  const Constraint& k = c.constraint;
  const Eigen::Vector2d si = c.vector("si"), sj = c.vector("sj");
  sketch.landmarks.push_back({k.i, si});
  sketch.landmarks.push_back({k.j, sj});
  sketch.struts.push_back({{k.i, si}, {k.j, sj}});
}

}  // namespace

extern const ConstraintKind kDistance{
    .name = "distance",
    .joint = true,
    .driver = true,
    .keys = {{"i", KeyKind::kBodyOrGround, true},
             {"j", KeyKind::kBodyOrGround, true},
             {"si", KeyKind::kOffset, false},
             {"sj", KeyKind::kOffset, false},
             {"length", KeyKind::kValue, true}},
    .rows = 1,
    .equations = equations,
    .draw = draw,
    .reaction_i = "si",
    .reaction_j = "sj",
    .squared_distance = true,
};

}  // namespace kinegen::codegen
