// absolute_x: the global x of point s of a body is `value` (a driver: f(t)).
#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> equations(const EquationContext& c) {
  const auto fi = c.frame_i();
  return {fi.x + EquationContext::rotate(fi.phi, c.vector("s")).first - c.value()};
}

// A fixed x: the point runs on a guide along global y. A driven coordinate moves on
// purpose: no guide to draw.
void draw(const DrawContext& c, Sketch& sketch) {
  const Constraint& k = c.constraint;
  const Eigen::Vector2d s = c.vector("s");
  sketch.landmarks.push_back({k.i, s});
  if (k.is_driver) return;
  const double v = c.value();
  sketch.sliders.push_back({{k.i, s}, kGround, Eigen::Vector2d(v, 0), Eigen::Vector2d::UnitY()});
}

}  // namespace

extern const ConstraintKind kAbsoluteX{
    .name = "absolute_x",
    .joint = true,
    .driver = true,
    .keys = {{"body", KeyKind::kBody, true},
             {"s", KeyKind::kOffset, false},
             {"value", KeyKind::kValue, true}},
    .rows = 1,
    .equations = equations,
    .draw = draw,
    .reaction_i = "s",
};

}  // namespace kinegen::codegen
