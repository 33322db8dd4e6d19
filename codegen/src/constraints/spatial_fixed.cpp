// fixed (spatial): a weld. d_ij = 0 (sj defaults to si carried into body j at the q0 pose) and
// the relative rotation at the q0 pose held: with (f_j, g_j, h_j) body i's frame axes carried
// into j there, (A_i x)^T (A_j g_j) = (A_i y)^T (A_j h_j) = (A_i z)^T (A_j f_j) = 0.
#include <array>

#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

// Body i's frame axes, global, and the same axes carried into body j at the q0 pose, global.
struct FixedAxes {
  std::array<spatial::V3, 3> i, j;
};
FixedAxes fixed_axes(const EquationContext& c) {
  using namespace spatial;
  const auto& k = c.constraint();
  const Eigen::Matrix3d carried = c.rotation0(k.j).transpose() * c.rotation0(k.i);
  FixedAxes axes;
  for (int a = 0; a < 3; ++a) {
    V3 e{0, 0, 0};
    e[a] = 1;
    axes.i[a] = global(c, k.i, e);
    axes.j[a] = global(c, k.j, exact(Eigen::Vector3d(carried.col(a))));
  }
  return axes;
}

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
  const FixedAxes a = fixed_axes(c);
  const auto d = c.d_ij3(si, sj);
  return {d[0], d[1], d[2], dot(a.i[0], a.j[1]), dot(a.i[1], a.j[2]), dot(a.i[2], a.j[0])};
}

// The three rows also hold at a half-turn about any frame axis and at a third of a turn about
// the diagonal: the weld's own orientation has every axis pair aligned.
BranchConditions fixed3_branch(const EquationContext& c) {
  using namespace spatial;
  const FixedAxes a = fixed_axes(c);
  return {{dot(a.i[0], a.j[0]), "x_i . x_j"},
          {dot(a.i[1], a.j[1]), "y_i . y_j"},
          {dot(a.i[2], a.j[2]), "z_i . z_j"}};
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

extern const SpatialBranch kSpatialFixedBranch{&kSpatialFixed, fixed3_branch};

}  // namespace kinegen::codegen
