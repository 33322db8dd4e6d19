// revolute_translational: a pin in a slot. Body j's point sj stays on the line through body
// i's point si along vi, (A_i vi)^perp . d_ij = 0; the bodies may turn.
#include "kinegen/codegen/constraints.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> equations(const EquationContext& c) { return {c.perpendicular(c.d_ij())}; }

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

}  // namespace

extern const ConstraintKind kRevoluteTranslational{
    .name = "revolute_translational",
    .joint = true,
    .driver = false,
    .keys = {{"i", KeyKind::kBodyOrGround, true},
             {"j", KeyKind::kBodyOrGround, true},
             {"si", KeyKind::kOffset, false},
             {"sj", KeyKind::kOffset, false},
             {"vi", KeyKind::kDirection, true}},
    .rows = 1,
    .equations = equations,
    .draw = draw,
    .reaction_i = "si",
    .reaction_j = "sj",
};

}  // namespace kinegen::codegen
