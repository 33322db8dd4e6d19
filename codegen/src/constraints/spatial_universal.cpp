// universal (spatial): a Hooke joint. d_ij = 0 and the cross axes stay perpendicular:
// (A_i axis_i)^T (A_j axis_j) = 0. Axes within 1 degree of parallel at the q0 pose are refused.
#include <numbers>

#include "kinegen/codegen/base/format.hpp"
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> universal_equations(const EquationContext& c) {
  using namespace spatial;
  const auto& k = c.constraint();
  const V3 ai = unit_axis(c, "axis_i"), aj = unit_axis(c, "axis_j");
  const Eigen::Vector3d gi = (c.rotation0(k.i) * numbers(c, ai)).normalized();
  const Eigen::Vector3d gj = (c.rotation0(k.j) * numbers(c, aj)).normalized();
  const double angle = std::acos(std::clamp(gi.dot(gj), -1.0, 1.0)) * 180 / std::numbers::pi;
  if (angle < 1 || angle > 179)
    c.fail("axis_j", "the axes are " + format_number(angle) +
                         " degrees apart at the q0 pose: within 1 degree of parallel, the "
                         "cross cannot assemble (they should be perpendicular)");
  const auto d = c.d_ij3();
  return {d[0], d[1], d[2], dot(global(c, k.i, ai), global(c, k.j, aj))};
}

std::string universal_row(const Constraint& c, int component) {
  return component < 3 ? spatial::xyz_row(c, component) : "axes perpendicular";
}

}  // namespace

extern const ConstraintKind kSpatialUniversal = spatial::spatial_two_point({
    .name = "universal",
    .joint = true,
    .driver = false,
    .keys = {{"axis_i", KeyKind::kDirection, true}, {"axis_j", KeyKind::kDirection, true}},
    .rows = 4,
    .equations = universal_equations,
    .row_name = universal_row,
});

}  // namespace kinegen::codegen
