// d (spatial): d_ij^T d_ij - length^2 = 0 (a driver gives the length as f(t)).
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> d_equations(const EquationContext& c) {
  const auto d = c.d_ij3();
  return {spatial::dot(d, d) - GiNaC::pow(c.value(), 2)};
}

}  // namespace

extern const ConstraintKind kSpatialD = spatial::spatial_two_point({
    .name = "d",
    .joint = true,
    .driver = true,
    .keys = {{"length", KeyKind::kValue, true}},
    .rows = 1,
    .equations = d_equations,
    .squared_distance = true,
});

}  // namespace kinegen::codegen
