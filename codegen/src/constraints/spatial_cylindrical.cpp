// cylindrical (spatial): the axes stay parallel, (A_i f_i)^T (A_j axis_j) =
// (A_i g_i)^T (A_j axis_j) = 0, and d_ij stays on axis_i, (A_i f_i)^T d_ij = (A_i g_i)^T d_ij = 0.
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> cylindrical_equations(const EquationContext& c) {
  using namespace spatial;
  const auto& k = c.constraint();
  const V3 ai = unit_axis(c, "axis_i"), aj = unit_axis(c, "axis_j");
  const Normals n = normals(c, ai);
  const V3 axis_j = global(c, k.j, aj);
  const V3 f = global(c, k.i, n.f), g = global(c, k.i, n.g);
  const auto d = c.d_ij3();
  return {dot(f, axis_j), dot(g, axis_j), dot(f, d), dot(g, d)};
}

BranchConditions cylindrical_branch(const EquationContext& c) { return {spatial::axes_aligned(c)}; }

std::string cylindrical_row(const Constraint&, int component) {
  const char* kNames[] = {"axis_j normal to f_i", "axis_j normal to g_i", "d_ij normal to f_i",
                          "d_ij normal to g_i"};
  return kNames[component];
}

}  // namespace

extern const ConstraintKind kSpatialCylindrical = spatial::spatial_two_point({
    .name = "cylindrical",
    .joint = true,
    .driver = false,
    .keys = {{"axis_i", KeyKind::kDirection, true}, {"axis_j", KeyKind::kDirection, true}},
    .rows = 4,
    .equations = cylindrical_equations,
    .row_name = cylindrical_row,
});

extern const SpatialBranch kSpatialCylindricalBranch{&kSpatialCylindrical, cylindrical_branch};

}  // namespace kinegen::codegen
