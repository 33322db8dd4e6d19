// cam_follower: two profiles in contact. curve_i(a) of body i and curve_j(b) of
// body j, in the extra coordinates a and b, touch: the contact points coincide (2) and the
// tangents are parallel, (A_i curve_i'(a))^perp . (A_j curve_j'(b)) = 0 (1). A roller is a
// circle, a flat face a line. Of the two contacts (from either side) the solver keeps the one
// it assembled on.
#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> cam_follower_equations(const EquationContext& c) {
  const Constraint& k = c.constraint();
  if (k.coordinates.at("coordinate_i") == k.coordinates.at("coordinate_j"))
    c.fail("coordinate_j", "coordinate_i and coordinate_j must be different coordinates");
  const auto fi = c.frame_i(), fj = c.frame_j();
  const auto ci = c.curve("curve_i", "coordinate_i"), cj = c.curve("curve_j", "coordinate_j");
  const auto pi = EquationContext::rotate(fi.phi, ci), pj = EquationContext::rotate(fj.phi, cj);
  const auto ti = EquationContext::rotate(fi.phi, c.tangent(ci, "coordinate_i"));
  const auto tj = EquationContext::rotate(fj.phi, c.tangent(cj, "coordinate_j"));
  return {fj.x + pj.first - fi.x - pi.first, fj.y + pj.second - fi.y - pi.second,
          -ti.second * tj.first + ti.first * tj.second};
}

// Both profiles, each on its body.
void cam_follower_draw(const DrawContext& c, Sketch& sketch) {
  const Constraint& k = c.constraint;
  sketch.curves.push_back(c.sampled_curve(k.i, "curve_i", "coordinate_i"));
  sketch.curves.push_back(c.sampled_curve(k.j, "curve_j", "coordinate_j"));
}

std::string cam_follower_row_name(const Constraint&, int component) {
  return component == 0 ? "contact x-component"
         : component == 1 ? "contact y-component"
                          : "tangency";
}

}  // namespace

// The contact point moves on both bodies, so the torque is reported about the body's origin;
// J.fn is the normal force (forces.hpp).
extern const ConstraintKind kCamFollower{
    .name = "cam_follower",
    .joint = true,
    .driver = false,
    .keys = {{"i", KeyKind::kBodyOrGround, true},
             {"curve_i", KeyKind::kCurve, true},
             {"coordinate_i", KeyKind::kCoordinate, true},
             {"j", KeyKind::kBodyOrGround, true},
             {"curve_j", KeyKind::kCurve, true},
             {"coordinate_j", KeyKind::kCoordinate, true}},
    .rows = 3,
    .equations = cam_follower_equations,
    .draw = cam_follower_draw,
    .row_name = cam_follower_row_name,
    .normal_force = true,
};

}  // namespace kinegen::codegen
