// absolute_angle: a body's angle is `value` (a driver: f(t)).
#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> absolute_angle_equations(const EquationContext& c) { return {c.frame_i().phi - c.value()}; }

}  // namespace

extern const ConstraintKind kAbsoluteAngle{
    .name = "absolute_angle",
    .joint = true,
    .driver = true,
    .keys = {{"body", KeyKind::kBody, true}, {"value", KeyKind::kValue, true}},
    .rows = 1,
    .equations = absolute_angle_equations,
};

}  // namespace kinegen::codegen
