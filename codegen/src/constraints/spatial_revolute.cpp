// revolute (spatial): a hinge. d_ij = 0 and axis_j stays perpendicular to f_i and g_i, the
// normals of axis_i: (A_i f_i)^T (A_j axis_j) = (A_i g_i)^T (A_j axis_j) = 0 (on the branch
// axis_i^T axis_j > 0, checked after every solve).
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> revolute3_equations(const EquationContext& c) {
  using namespace spatial;
  const auto& k = c.constraint();
  const V3 ai = unit_axis(c, "axis_i"), aj = unit_axis(c, "axis_j");
  const Normals n = normals(c, ai);
  const V3 axis_j = global(c, k.j, aj);
  const auto d = c.d_ij3();
  return {d[0], d[1], d[2], dot(global(c, k.i, n.f), axis_j), dot(global(c, k.i, n.g), axis_j)};
}

BranchConditions revolute3_branch(const EquationContext& c) { return {spatial::axes_aligned(c)}; }

std::string revolute3_row(const Constraint& c, int component) {
  return component < 3    ? spatial::xyz_row(c, component)
         : component == 3 ? "axis_j normal to f_i"
                          : "axis_j normal to g_i";
}

}  // namespace

extern const ConstraintKind kSpatialRevolute = spatial::spatial_two_point({
    .name = "revolute",
    .joint = true,
    .driver = false,
    .keys = {{"axis_i", KeyKind::kDirection, true}, {"axis_j", KeyKind::kDirection, true}},
    .rows = 5,
    .equations = revolute3_equations,
    .row_name = revolute3_row,
});

extern const SpatialBranch kSpatialRevoluteBranch{&kSpatialRevolute, revolute3_branch};

}  // namespace kinegen::codegen
