// The Euler parameter normalization of a spatial body, p^T p - 1 = 0 (Jacobian 2 p^T, nu 0,
// gamma -2 pdot^T pdot): the tool's own row, one per body (`euler_<body>`), never in a file's
// joints or drivers (Mechanism::normalization).
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> euler_equations(const EquationContext& c) {
  const auto p = c.frame3(c.constraint().i).p;
  return {p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3] - 1};
}

}  // namespace

extern const ConstraintKind kEulerNormalization{
    .name = "euler_parameters",
    .joint = false,
    .driver = false,
    .keys = {{"body", KeyKind::kBody, true}},
    .rows = 1,
    .equations = euler_equations,
    .reaction = false,
    .space = KindSpace::kSpatial,
};

}  // namespace kinegen::codegen
