// fixed (spatial): a weld. d_ij = 0 (sj defaults to si carried into body j at the q0 pose) and
// the relative rotation at the q0 pose held: with (f_j, g_j, h_j) body i's frame axes carried
// into j there, (A_i x)^T (A_j g_j) = (A_i y)^T (A_j h_j) = (A_i z)^T (A_j f_j) = 0.
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> fixed3_equations(const EquationContext& c) {
  using namespace spatial;
  const auto& k = c.constraint();
  const V3 si = c.vector3("si");
  V3 sj;
  if (k.vector("sj").x.text.empty()) {
    const Eigen::Vector3d at = c.origin0(k.i) + c.rotation0(k.i) * numbers(c, si);
    sj = exact(c.rotation0(k.j).transpose() * (at - c.origin0(k.j)));
  } else {
    sj = c.vector3("sj");
  }
  const Eigen::Matrix3d carried = c.rotation0(k.j).transpose() * c.rotation0(k.i);
  const auto axis_i = [&](int a) {
    V3 e{0, 0, 0};
    e[a] = 1;
    return global(c, k.i, e);
  };
  const auto axis_j = [&](int a) { return global(c, k.j, exact(Eigen::Vector3d(carried.col(a)))); };
  const auto d = c.d_ij3(si, sj);
  return {d[0],
          d[1],
          d[2],
          dot(axis_i(0), axis_j(1)),
          dot(axis_i(1), axis_j(2)),
          dot(axis_i(2), axis_j(0))};
}

std::string fixed3_row(const Constraint& c, int component) {
  const char* kNames[] = {"x_i normal to y_j", "y_i normal to z_j", "z_i normal to x_j"};
  return component < 3 ? spatial::xyz_row(c, component) : kNames[component - 3];
}

}  // namespace

extern const ConstraintKind kSpatialFixed = [] {
  ConstraintKind kind = spatial::spatial_two_point({
      .name = "fixed",
      .joint = true,
      .driver = false,
      .keys = {},
      .rows = 6,
      .equations = fixed3_equations,
      .row_name = fixed3_row,
  });
  kind.keys[3].default_value = "";  // sj: si carried into j at the q0 pose
  return kind;
}();

}  // namespace kinegen::codegen
