// dp2 (spatial): vector ai of body i and d_ij keep the dot product `value` (a driver: f(t)):
// (A_i ai)^T d_ij - f = 0.
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> dp2_equations(const EquationContext& c) {
  using namespace spatial;
  return {dot(global(c, c.constraint().i, c.vector3("ai")), c.d_ij3()) - c.value()};
}

}  // namespace

extern const ConstraintKind kSpatialDp2 = spatial::spatial_two_point({
    .name = "dp2",
    .joint = true,
    .driver = true,
    .keys = {{"ai", KeyKind::kDirection, true}, {"value", KeyKind::kValue, false}},
    .rows = 1,
    .equations = dp2_equations,
    .reaction = false,
});

}  // namespace kinegen::codegen
