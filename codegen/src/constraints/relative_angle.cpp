// relative_angle: body j's angle minus body i's is `value` (a driver: f(t)).
#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> relative_angle_equations(const EquationContext& c) {
  return {c.frame_j().phi - c.frame_i().phi - c.value()};
}

}  // namespace

extern const ConstraintKind kRelativeAngle{
    .name = "relative_angle",
    .joint = true,
    .driver = true,
    .keys = {{"i", KeyKind::kBodyOrGround, true},
             {"j", KeyKind::kBodyOrGround, true},
             {"value", KeyKind::kValue, true}},
    .rows = 1,
    .equations = relative_angle_equations,
};

}  // namespace kinegen::codegen
