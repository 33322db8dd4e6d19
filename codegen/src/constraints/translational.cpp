// translational: a slider without rotation. Body j's point sj stays on the line through body
// i's point si along vi, (A_i vi)^perp . d_ij = 0, and the relative angle stays at `angle`.
#include "kinegen/codegen/constraints.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> equations(const EquationContext& c) {
  const auto d = c.d_ij();
  return {c.perpendicular(d), c.frame_j().phi - c.frame_i().phi - c.value()};
}

// A block sliding on a guide fixed in body i (a slot when i moves).
void draw(const DrawContext& c, Sketch& sketch) {
  const Constraint& k = c.constraint;
  const Eigen::Vector2d si = c.vector("si"), sj = c.vector("sj");
  Eigen::Vector2d vi = c.vector("vi");
  sketch.landmarks.push_back({k.i, si});
  sketch.landmarks.push_back({k.j, sj});
  if (vi.norm() > 0) vi.normalize();
  sketch.sliders.push_back({{k.j, sj}, k.i, si, vi});
}

std::string row_name(const Constraint&, int component) {
  return component == 0 ? "normal offset" : "relative angle";
}

}  // namespace

extern const ConstraintKind kTranslational{
    .name = "translational",
    .joint = true,
    .driver = false,
    .keys = {{"i", KeyKind::kBodyOrGround, true},
             {"j", KeyKind::kBodyOrGround, true},
             {"si", KeyKind::kOffset, false},
             {"sj", KeyKind::kOffset, false},
             {"vi", KeyKind::kDirection, true},
             {"angle", KeyKind::kValue, false}},
    .rows = 2,
    .equations = equations,
    .draw = draw,
    .row_name = row_name,
    .reaction_i = "si",
    .reaction_j = "sj",
};

}  // namespace kinegen::codegen
