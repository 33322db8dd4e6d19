// gear: a pair of gears rolling on their pitch circles (radii ri, rj about the pitch centres
// si of body i and sj of body j), external or internal (`internal: true`: j is the ring, i
// runs inside it, rj > ri). The line of centres, d_ij from centre i to centre j, has the
// direction angle
//   psi = (ri phi_i + rj phi_j - c) / (ri + rj)     (external)
//   psi = (rj phi_j - ri phi_i + c) / (rj - ri)     (internal),
// which is no slip at the pitch point, ri (phi_i - psi) +- rj (phi_j - psi) = c. The equation
// is d_ij . [-sin psi, cos psi] = 0: psi enters only through sin and cos, so it is smooth
// when the line of centres turns through +-pi (a planetary carrier does every revolution),
// where an atan2 of d_ij would jump. The centre distance is left to other joints; it is only
// checked at assembly (a warning).
#include <cmath>
#include <sstream>

#include "common.hpp"
#include "kinegen/codegen/base/format.hpp"

namespace kinegen::codegen {

namespace {

using GiNaC::ex;

// The pitch radii, checked: positive, and for an internal pair the ring's the larger.
std::pair<ex, ex> radii(const EquationContext& c) {
  const ex ri = c.scalar("ri"), rj = c.scalar("rj");
  if (!(c.number(ri) > 0)) c.fail("ri", "ri (a pitch radius) must be > 0");
  if (!(c.number(rj) > 0)) c.fail("rj", "rj (a pitch radius) must be > 0");
  if (c.flag("internal") && !(c.number(rj) > c.number(ri)))
    c.fail("rj", "an internal pair needs rj > ri (j is the ring, i runs inside it)");
  return {ri, rj};
}

std::vector<ex> gear_equations(const EquationContext& c) {
  const auto [ri, rj] = radii(c);
  const ex offset = c.scalar("c");
  const ex phi_i = c.frame_i().phi, phi_j = c.frame_j().phi;
  const ex psi = c.flag("internal") ? (rj * phi_j - ri * phi_i + offset) / (rj - ri)
                                    : (ri * phi_i + rj * phi_j - offset) / (ri + rj);
  const auto d = c.d_ij();
  return {-d.first * GiNaC::sin(psi) + d.second * GiNaC::cos(psi)};
}

// The two pitch circles, each with a radius mark that turns with its body.
void gear_draw(const DrawContext& c, Sketch& sketch) {
  const TwoPoints p = draw_two_points(c, sketch);
  sketch.pitch_circles.push_back({p.i, c.scalar("ri")});
  sketch.pitch_circles.push_back({p.j, c.scalar("rj")});
}

Eigen::Vector2d world_point(const Eigen::VectorXd& q, int body, const Eigen::Vector2d& s) {
  if (body == kGround) return s;
  const double phi = q[3 * body + 2], co = std::cos(phi), sn = std::sin(phi);
  return {q[3 * body] + co * s[0] - sn * s[1], q[3 * body + 1] + sn * s[0] + co * s[1]};
}

double angle_of(const Eigen::VectorXd& q, int body) {
  return body == kGround ? 0.0 : q[3 * body + 2];
}

// The pitch circles touch only at the centre distance ri + rj (rj - ri internal), along psi.
std::string assembly_warning(const DrawContext& c, const Eigen::VectorXd& q) {
  const Constraint& k = c.constraint;  // the message is about it: analysis adds file, line, item
  const bool internal = k.flags.at("internal");
  const double ri = c.scalar("ri"), rj = c.scalar("rj"), offset = c.scalar("c");
  const double phi_i = angle_of(q, k.i), phi_j = angle_of(q, k.j);
  const double psi = internal ? (rj * phi_j - ri * phi_i + offset) / (rj - ri)
                              : (ri * phi_i + rj * phi_j - offset) / (ri + rj);
  const Eigen::Vector2d d =
      world_point(q, k.j, c.vector("sj")) - world_point(q, k.i, c.vector("si"));
  const double along = d.dot(Eigen::Vector2d(std::cos(psi), std::sin(psi)));
  const double expected = internal ? rj - ri : ri + rj;
  constexpr double kRelTol = 1e-6;
  if (std::abs(along - expected) <= kRelTol * expected) return "";
  const auto n = [](double v) { return format_number(v, NumberStyle::kShort); };
  std::ostringstream os;
  if (along < 0)
    os << "at assembly the line of centres points against psi (c is off by half a turn "
          "of psi, "
       << n(expected * std::acos(-1.0)) << "); the velocities are right, the pitch point "
       << "is on the far side";
  else
    os << "at assembly the centre distance is " << n(d.norm()) << ", not "
       << (internal ? "rj - ri = " : "ri + rj = ") << n(expected)
       << ": the pitch circles do not touch (the other joints hold the centres)";
  return os.str();
}

}  // namespace

extern const ConstraintKind kGear = two_point_joint({
    .name = "gear",
    .joint = true,
    .driver = false,
    .keys = {{"ri", KeyKind::kScalar, true},
             {"rj", KeyKind::kScalar, true},
             {"internal", KeyKind::kFlag, false, "false"},
             {"c", KeyKind::kScalar, false}},
    .rows = 1,
    .equations = gear_equations,
    .draw = gear_draw,
    .assembly_warning = assembly_warning,
});

}  // namespace kinegen::codegen
