// absolute_x and absolute_y: the global x (y) of point s of a body is `value` (a driver: f(t)).
// One file for the pair: they differ only in the axis.
#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

namespace {

template <int kAxis>  // 0: x, 1: y
std::vector<GiNaC::ex> absolute_xy_equations(const EquationContext& c) {
  const auto fi = c.frame_i();
  const auto s = EquationContext::rotate(fi.phi, c.vector("s"));
  if constexpr (kAxis == 0) return {fi.x + s.first - c.value()};
  return {fi.y + s.second - c.value()};
}

// A fixed x (y): the point runs on a guide along global y (x). A driven coordinate moves on
// purpose: no guide to draw.
template <int kAxis>
void absolute_xy_draw(const DrawContext& c, Sketch& sketch) {
  const Constraint& k = c.constraint;
  const Eigen::Vector2d s = c.vector("s");
  sketch.landmarks.push_back({k.i, s});
  if (k.is_driver) return;
  Eigen::Vector2d at = Eigen::Vector2d::Zero();
  at[kAxis] = c.value();
  sketch.sliders.push_back({{k.i, s}, kGround, at, Eigen::Vector2d::Unit(1 - kAxis)});
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
    .equations = absolute_xy_equations<0>,
    .draw = absolute_xy_draw<0>,
    .reaction_i = "s",
};

extern const ConstraintKind kAbsoluteY{
    .name = "absolute_y",
    .joint = true,
    .driver = true,
    .keys = {{"body", KeyKind::kBody, true},
             {"s", KeyKind::kOffset, false},
             {"value", KeyKind::kValue, true}},
    .rows = 1,
    .equations = absolute_xy_equations<1>,
    .draw = absolute_xy_draw<1>,
    .reaction_i = "s",
};

}  // namespace kinegen::codegen
