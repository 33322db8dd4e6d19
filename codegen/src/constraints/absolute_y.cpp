// absolute_y: the global y of point s of a body is `value` (a driver: f(t)).
#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> equations(const EquationContext& c) {
  const auto fi = c.frame_i();
  return {fi.y + EquationContext::rotate(fi.phi, c.vector("s")).second - c.value()};
}

// A fixed y: the point runs on a guide along global x. A driven coordinate moves on
// purpose: no guide to draw.
void draw(const DrawContext& c, Sketch& sketch) {
  const Constraint& k = c.constraint;
  const Eigen::Vector2d s = c.vector("s");
  sketch.landmarks.push_back({k.i, s});
  if (k.is_driver) return;
  const double v = c.value();
  sketch.sliders.push_back({{k.i, s}, kGround, Eigen::Vector2d(0, v), Eigen::Vector2d::UnitX()});
}

}  // namespace

extern const ConstraintKind kAbsoluteY{
    .name = "absolute_y",
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
