// rack_pinion: a pinion (body j, pitch centre sj, pitch radius rj) rolling on a rack (body i,
// pitch line through si along vi). With u = unit(A_i vi) and d = d_ij (pinion centre minus
// the line's point): u^perp . d - rj = 0 (the centre lies rj to the left of the line) and
// u . d + rj (phi_j - phi_i) - c = 0 (no slip: the centre advances rj per radian the pinion
// turns clockwise relative to the rack).
#include "kinegen/codegen/constraints.hpp"

namespace kinegen::codegen {

namespace {

using GiNaC::ex;

std::vector<ex> equations(const EquationContext& c) {
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
void draw(const DrawContext& c, Sketch& sketch) {
  const Constraint& k = c.constraint;
  const Eigen::Vector2d si = c.vector("si"), sj = c.vector("sj");
  Eigen::Vector2d vi = c.vector("vi");
  if (vi.norm() > 0) vi.normalize();
  sketch.landmarks.push_back({k.i, si});
  sketch.landmarks.push_back({k.j, sj});
  sketch.pitch_circles.push_back({{k.j, sj}, c.scalar("rj")});
  sketch.pitch_lines.push_back({{k.j, sj}, k.i, si, vi});
}

std::string row_name(const Constraint&, int component) {
  return component == 0 ? "distance from the pitch line" : "rolling";
}

}  // namespace

extern const ConstraintKind kRackPinion{
    .name = "rack_pinion",
    .joint = true,
    .driver = false,
    .keys = {{"i", KeyKind::kBodyOrGround, true},
             {"si", KeyKind::kOffset, false},
             {"vi", KeyKind::kDirection, true},
             {"j", KeyKind::kBodyOrGround, true},
             {"sj", KeyKind::kOffset, false},
             {"rj", KeyKind::kScalar, true},
             {"c", KeyKind::kScalar, false}},
    .rows = 2,
    .equations = equations,
    .draw = draw,
    .row_name = row_name,
    .reaction_i = "si",
    .reaction_j = "sj",
};

}  // namespace kinegen::codegen
