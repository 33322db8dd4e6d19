// distance (spatial): a link with a ball at each end (a tie rod, a strut): points si of body i
// and sj of body j stay `length` apart, d_ij^T d_ij - length^2 = 0.
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> distance3_equations(const EquationContext& c) {
  const auto d = c.d_ij3();
  return {spatial::dot(d, d) - GiNaC::pow(c.value(), 2)};
}

}  // namespace

extern const ConstraintKind kSpatialDistance = spatial::spatial_two_point({
    .name = "distance",
    .joint = true,
    .driver = true,
    .keys = {{"length", KeyKind::kValue, true}},
    .rows = 1,
    .equations = distance3_equations,
    .squared_distance = true,
});

}  // namespace kinegen::codegen
