// rack_pinion: a pinion (body j, pitch centre sj, pitch radius rj) rolling on a rack (body i,
// pitch line through si along vi). With u = unit(A_i vi) and d = d_ij (pinion centre minus
// the line's point): u^perp . d - rj = 0 (the centre lies rj to the left of the line) and
// u . d + rj (phi_j - phi_i) - c = 0 (no slip: the centre advances rj per radian the pinion
// turns clockwise relative to the rack).
#include "common.hpp"

namespace kinegen::codegen {

namespace {

using GiNaC::ex;

std::vector<ex> rack_pinion_equations(const EquationContext& c) {
  const ex rj = c.scalar("rj");
  if (!(c.number(rj) > 0)) c.fail("rj", "rj (the pinion's pitch radius) must be > 0");
  const auto d = c.d_ij();
  const auto v = c.vector("vi");
  const ex length = GiNaC::sqrt(GiNaC::pow(v.first, 2) + GiNaC::pow(v.second, 2));
  const ex normal = c.perpendicular(d) / length;  // refuses vi = 0
  const auto u = EquationContext::rotate(c.frame_i().phi, v);
  const ex along = (u.first * d.first + u.second * d.second) / length;
  return {normal - rj, along + rj * (c.frame_j().phi - c.frame_i().phi) - c.scalar("c")};
}

// The pinion's pitch circle and the rack's pitch line along the pinion's travel.
void rack_pinion_draw(const DrawContext& c, Sketch& sketch) {
  const TwoPoints p = draw_two_points(c, sketch);
  sketch.pitch_circles.push_back({p.j, c.scalar("rj")});
  sketch.pitch_lines.push_back({p.j, p.i.body, p.i.s, unit_direction(c, "vi")});
}

std::string rack_pinion_row_name(const Constraint&, int component) {
  return component == 0 ? "distance from the pitch line" : "rolling";
}

}  // namespace

extern const ConstraintKind kRackPinion = two_point_joint({
    .name = "rack_pinion",
    .joint = true,
    .driver = false,
    .keys = {{"vi", KeyKind::kDirection, true},
             {"rj", KeyKind::kScalar, true},
             {"c", KeyKind::kScalar, false}},
    .rows = 2,
    .equations = rack_pinion_equations,
    .draw = rack_pinion_draw,
    .row_name = rack_pinion_row_name,
});

}  // namespace kinegen::codegen
