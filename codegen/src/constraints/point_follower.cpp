// point_follower: a pin in a curved slot. Point sj of body j lies on the curve [x(u), y(u)] of
// body i at the value of the extra coordinate u:
// r_j + A_j sj - r_i - A_i curve(u) = 0.
#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> point_follower_equations(const EquationContext& c) {
  const auto fi = c.frame_i(), fj = c.frame_j();
  const auto on_i = EquationContext::rotate(fi.phi, c.curve("curve", "coordinate"));
  const auto on_j = EquationContext::rotate(fj.phi, c.vector("sj"));
  return {fj.x + on_j.first - fi.x - on_i.first, fj.y + on_j.second - fi.y - on_i.second};
}

// The slot on body i and the pin on body j.
void point_follower_draw(const DrawContext& c, Sketch& sketch) {
  const Constraint& k = c.constraint;
  const Eigen::Vector2d sj = c.vector("sj");
  sketch.landmarks.push_back({k.j, sj});
  sketch.pins.push_back({k.j, sj});
  if (k.j == kGround) sketch.ground_pivots.push_back(sj);
  sketch.curves.push_back(c.sampled_curve(k.i, "curve", "coordinate"));
}

std::string point_follower_row_name(const Constraint&, int component) {
  return component == 0 ? "x-component" : "y-component";
}

}  // namespace

// The reaction on j acts at the pin; on i (j = ground) it is reported about i's origin, since
// the contact point moves along the slot.
extern const ConstraintKind kPointFollower{
    .name = "point_follower",
    .joint = true,
    .driver = false,
    .keys = {{"i", KeyKind::kBodyOrGround, true},
             {"curve", KeyKind::kCurve, true},
             {"coordinate", KeyKind::kCoordinate, true},
             {"j", KeyKind::kBodyOrGround, true},
             {"sj", KeyKind::kOffset, false}},
    .rows = 2,
    .equations = point_follower_equations,
    .draw = point_follower_draw,
    .row_name = point_follower_row_name,
    .reaction_i = nullptr,
    .reaction_j = "sj",
};

}  // namespace kinegen::codegen
