// translational (spatial): a prismatic joint. A cylindrical joint with the rotation about the
// axis locked: (A_i ref_i)^T (A_j (axis_j x ref_j)) = 0, on the branch axis_i^T axis_j > 0 and
// ref_i^T ref_j > 0. By
// default ref_i is f_i and ref_j is ref_i carried into body j at the q0 pose.
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

// ref_i and ref_j, unit, in their bodies' frames (translational_refs is used by the branch check).
std::pair<spatial::V3, spatial::V3> translational_refs(const EquationContext& c) {
  using namespace spatial;
  const auto& k = c.constraint();
  const V3 ai = unit_axis(c, "axis_i"), aj = unit_axis(c, "axis_j");
  const bool given_i = !k.vector("ref_i").x.text.empty(),
             given_j = !k.vector("ref_j").x.text.empty();
  const V3 ref_i = given_i ? unit_axis(c, "ref_i") : normals(c, ai).f;
  if (given_j) return {ref_i, unit_axis(c, "ref_j")};
  const Eigen::Matrix3d rj = aligned_rotation0(c, numbers(c, ai), numbers(c, aj));
  return {ref_i, exact(carried(rj, c.rotation0(k.i) * numbers(c, ref_i)).normalized())};
}

std::vector<GiNaC::ex> translational3_equations(const EquationContext& c) {
  using namespace spatial;
  const auto& k = c.constraint();
  const V3 ai = unit_axis(c, "axis_i"), aj = unit_axis(c, "axis_j");
  const Normals n = normals(c, ai);
  const V3 axis_j = global(c, k.j, aj);
  const V3 f = global(c, k.i, n.f), g = global(c, k.i, n.g);
  const auto d = c.d_ij3();
  const auto [ref_i, ref_j] = translational_refs(c);
  return {dot(f, axis_j), dot(g, axis_j), dot(f, d), dot(g, d),
          dot(global(c, k.i, ref_i), global(c, k.j, cross(aj, ref_j)))};
}

BranchConditions translational3_branch(const EquationContext& c) {
  using namespace spatial;
  const auto& k = c.constraint();
  const auto [ref_i, ref_j] = translational_refs(c);
  // The axes too: a half-turn of j about ref_i keeps every row and ref_j, flipping axis_j.
  return {axes_aligned(c), {dot(global(c, k.i, ref_i), global(c, k.j, ref_j)), "ref_i . ref_j"}};
}

std::string translational3_row(const Constraint&, int component) {
  const char* kNames[] = {"axis_j normal to f_i", "axis_j normal to g_i", "d_ij normal to f_i",
                          "d_ij normal to g_i", "rotation lock"};
  return kNames[component];
}

}  // namespace

extern const ConstraintKind kSpatialTranslational = spatial::spatial_two_point({
    .name = "translational",
    .joint = true,
    .driver = false,
    .keys = {{"axis_i", KeyKind::kDirection, true},
             {"axis_j", KeyKind::kDirection, true},
             {"ref_i", KeyKind::kDirection, false, ""},
             {"ref_j", KeyKind::kDirection, false, ""}},
    .rows = 5,
    .equations = translational3_equations,
    .row_name = translational3_row,
});

extern const SpatialBranch kSpatialTranslationalBranch{&kSpatialTranslational,
                                                       translational3_branch};

}  // namespace kinegen::codegen
