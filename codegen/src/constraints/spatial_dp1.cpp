// dp1 (spatial): vectors ai of body i and aj of body j keep the dot product `value` (a driver:
// f(t)): (A_i ai)^T (A_j aj) - f = 0. The vectors are used as given.
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> dp1_equations(const EquationContext& c) {
  using namespace spatial;
  const auto& k = c.constraint();
  return {dot(global(c, k.i, c.vector3("ai")), global(c, k.j, c.vector3("aj"))) - c.value()};
}

}  // namespace

extern const ConstraintKind kSpatialDp1{
    .name = "dp1",
    .joint = true,
    .driver = true,
    .keys = {{"i", KeyKind::kBodyOrGround, true},
             {"j", KeyKind::kBodyOrGround, true},
             {"ai", KeyKind::kDirection, true},
             {"aj", KeyKind::kDirection, true},
             {"value", KeyKind::kValue, false}},
    .rows = 1,
    .equations = dp1_equations,
    .reaction = false,
    .space = KindSpace::kSpatial,
};

}  // namespace kinegen::codegen
