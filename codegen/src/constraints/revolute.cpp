// revolute: a pin. Point si of body i and point sj of body j coincide: d_ij = 0.
#include "kinegen/codegen/constraints.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> equations(const EquationContext& c) {
  const auto d = c.d_ij();
  return {d.first, d.second};
}

void draw(const DrawContext& c, Sketch& sketch) {
  const Constraint& k = c.constraint;
  const Eigen::Vector2d si = c.vector("si"), sj = c.vector("sj");
  sketch.landmarks.push_back({k.i, si});
  sketch.landmarks.push_back({k.j, sj});
  sketch.pins.push_back({k.i, si});
  if (k.i == kGround) sketch.ground_pivots.push_back(si);
  if (k.j == kGround) sketch.ground_pivots.push_back(sj);
}

std::string row_name(const Constraint&, int component) {
  return component == 0 ? "x-component" : "y-component";
}

}  // namespace

extern const ConstraintKind kRevolute{
    .name = "revolute",
    .joint = true,
    .driver = false,
    .keys = {{"i", KeyKind::kBodyOrGround, true},
             {"j", KeyKind::kBodyOrGround, true},
             {"si", KeyKind::kOffset, false},
             {"sj", KeyKind::kOffset, false}},
    .rows = 2,
    .equations = equations,
    .draw = draw,
    .row_name = row_name,
    .reaction_i = "si",
    .reaction_j = "sj",
};

}  // namespace kinegen::codegen
