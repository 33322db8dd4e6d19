// cd (spatial): the component of d_ij along the constant global vector c is `value` (a driver:
// f(t)): c^T d_ij - f = 0.
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> cd_equations(const EquationContext& c) {
  return {spatial::dot(c.vector3("c"), c.d_ij3()) - c.value()};
}

}  // namespace

extern const ConstraintKind kSpatialCd = spatial::spatial_two_point({
    .name = "cd",
    .joint = true,
    .driver = true,
    .keys = {{"c", KeyKind::kDirection, true}, {"value", KeyKind::kValue, false}},
    .rows = 1,
    .equations = cd_equations,
    .reaction = false,
});

}  // namespace kinegen::codegen
