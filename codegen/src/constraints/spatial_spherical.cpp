// spherical: a ball joint. Point si of body i and point sj of body j coincide: d_ij = 0.
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> spherical_equations(const EquationContext& c) {
  const auto d = c.d_ij3();
  return {d[0], d[1], d[2]};
}

}  // namespace

extern const ConstraintKind kSpatialSpherical = spatial::spatial_two_point({
    .name = "spherical",
    .joint = true,
    .driver = false,
    .keys = {},
    .rows = 3,
    .equations = spherical_equations,
    .row_name = spatial::xyz_row,
});

}  // namespace kinegen::codegen
