// Kinetostatics, the symbolic half: Q^A, the mass data and the reaction points (see
// symbolic/forces.hpp).
#include "kinegen/codegen/symbolic/forces.hpp"

#include <cmath>

#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"
#include "symbolic_detail.hpp"

namespace kinegen::codegen {

namespace {

using GiNaC::ex;

struct Vec {
  ex x, y;
};

class Builder {
 public:
  Builder(const Mechanism& m, const SymbolTable& s, const SymbolicModel& model)
      : m_(m), s_(s), values_(model.param_values) {}

  ex parse(const Expr& e, Scope scope, const std::string& item) const {
    return s_.parse(e, scope, item);
  }
  double number(const Expr& e, const std::string& item, bool nonnegative) const {
    const double v = to_double(substitute_params(parse(e, Scope::kGeometry, item), s_, values_));
    if (!std::isfinite(v))
      throw InputError(m_.source, item, e.loc, "'" + e.text + "' is not a finite number");
    if (nonnegative && v < 0)
      throw InputError(m_.source, item, e.loc, "'" + e.text + "' must not be negative");
    return v;
  }
  // A constant with the parameters' values substituted, exact where they are exact.
  ex exact(const Expr& e, const std::string& item) const {
    return substitute_params(parse(e, Scope::kGeometry, item), s_, values_);
  }
  std::array<ex, 2> exact(const Vec2& v, const std::string& item) const {
    return {exact(v.x, item), exact(v.y, item)};
  }
  Vec vec(const Vec2& v, Scope scope, const std::string& item) const {
    return {parse(v.x, scope, item), parse(v.y, scope, item)};
  }
  // A s for body b (ground: s itself).
  Vec rotated(int b, const Vec& s) const {
    if (b == kGround) return s;
    const ex phi = s_.q(3 * b + 2);
    return {cos(phi) * s.x - sin(phi) * s.y, sin(phi) * s.x + cos(phi) * s.y};
  }
  Vec point(int b, const Vec& s) const {
    const Vec a = rotated(b, s);
    if (b == kGround) return a;
    return {s_.q(3 * b) + a.x, s_.q(3 * b + 1) + a.y};
  }
  ex angle(int b) const { return b == kGround ? ex(0) : ex(s_.q(3 * b + 2)); }
  ex rate(int b) const { return b == kGround ? ex(0) : ex(s_.qd(3 * b + 2)); }
  // d/dt of an expression in q along qd.
  ex time_derivative(const ex& e) const {
    ex d = 0;
    for (int k = 0; k < s_.nq(); ++k) d += e.diff(s_.q(k)) * s_.qd(k);
    return d;
  }
  // A force (global components) at local point s of body b, into Q.
  void add_force(std::vector<ex>& q, int b, const Vec& s, const ex& fx, const ex& fy) const {
    if (b == kGround) return;
    const Vec a = rotated(b, s);
    q[3 * b] += fx;
    q[3 * b + 1] += fy;
    q[3 * b + 2] += a.x * fy - a.y * fx;  // (A s) x F
  }
  // A force's component or a torque's value: its expression, or for a component written
  // `input` (Load::Input) the run-time input (slot 3 (drivers + index), like an input
  // driver's value), or the table --input gave it.
  ex load_value(const Load& load, const Expr& e, int component, const std::string& item) const {
    for (const Load::Input& in : load.inputs) {
      if (in.component != component) continue;
      if (in.table_id >= 0) return kinegen_table(in.table_id, 0, s_.t());
      return kinegen_input(static_cast<int>(m_.drivers.size()) + in.index, 0, s_.t());
    }
    return parse(e, Scope::kLoad, item);
  }
  void add_torque(std::vector<ex>& q, int b, const ex& tz) const {
    if (b != kGround) q[3 * b + 2] += tz;
  }

 private:
  const Mechanism& m_;
  const SymbolTable& s_;
  const std::vector<GiNaC::numeric>& values_;
};

// A load's generalized forces, added to Q^A, and its part of the potential (springs) or of
// Q^nc (the rest: force and torque loads, dampers).
void add_load(const Builder& b, const Load& load, ForceModel& f) {
  switch (load.kind) {
    case Load::Kind::kForce: {
      const Vec fv{b.load_value(load, load.f.x, 0, load.item + " f"),
                   b.load_value(load, load.f.y, 1, load.item + " f")};
      const Vec at = b.vec(load.s, Scope::kGeometry, load.item + " s");
      for (auto* q : {&f.applied, &f.nonconservative}) b.add_force(*q, load.body, at, fv.x, fv.y);
      break;
    }
    case Load::Kind::kTorque: {
      const ex tz = b.load_value(load, load.value, 2, load.item);
      for (auto* q : {&f.applied, &f.nonconservative}) b.add_torque(*q, load.body, tz);
      break;
    }
    case Load::Kind::kSpringDamper: {
      const Vec si = b.vec(load.si, Scope::kGeometry, load.item + " si");
      const Vec sj = b.vec(load.sj, Scope::kGeometry, load.item + " sj");
      const Vec pi = b.point(load.i, si), pj = b.point(load.j, sj);
      const ex dx = pj.x - pi.x, dy = pj.y - pi.y;
      const ex length = sqrt(dx * dx + dy * dy);
      const ex rate = (dx * b.time_derivative(dx) + dy * b.time_derivative(dy)) / length;
      const ex stiffness = b.parse(load.stiffness, Scope::kGeometry, load.item + " stiffness");
      const ex stretch = length - b.parse(load.length0, Scope::kGeometry, load.item + " length0");
      const ex preload = b.parse(load.preload, Scope::kGeometry, load.item + " preload");
      const ex damping = b.parse(load.damping, Scope::kGeometry, load.item + " damping") * rate;
      const ex tension = stiffness * stretch + damping + preload;
      // Tension pulls the points together: along -d on j, along +d on i.
      b.add_force(f.applied, load.j, sj, -tension * dx / length, -tension * dy / length);
      b.add_force(f.applied, load.i, si, tension * dx / length, tension * dy / length);
      b.add_force(f.nonconservative, load.j, sj, -damping * dx / length, -damping * dy / length);
      b.add_force(f.nonconservative, load.i, si, damping * dx / length, damping * dy / length);
      f.potential += stiffness * stretch * stretch / 2 + preload * length;
      break;
    }
    case Load::Kind::kRotationalSpringDamper: {
      const ex stiffness = b.parse(load.stiffness, Scope::kGeometry, load.item + " stiffness");
      const ex twist = b.angle(load.j) - b.angle(load.i) -
                       b.parse(load.angle0, Scope::kGeometry, load.item + " angle0");
      const ex damping = b.parse(load.damping, Scope::kGeometry, load.item + " damping") *
                         (b.rate(load.j) - b.rate(load.i));
      const ex torque = -(stiffness * twist + damping);
      b.add_torque(f.applied, load.j, torque);
      b.add_torque(f.applied, load.i, -torque);
      b.add_torque(f.nonconservative, load.j, -damping);
      b.add_torque(f.nonconservative, load.i, damping);
      f.potential += stiffness * twist * twist / 2;
      break;
    }
  }
}

}  // namespace

ForceModel derive_forces(const Mechanism& m, const SymbolTable& s, const SymbolicModel& model,
                         const ForceSpec& spec) {
  const Builder b(m, s, model);
  ForceModel f;
  const int nb = static_cast<int>(m.bodies.size());
  f.applied.assign(s.nq(), ex(0));
  f.nonconservative.assign(s.nq(), ex(0));
  f.potential = 0;
  const Vec g = b.vec(spec.gravity, Scope::kGeometry, "gravity");
  b.number(spec.gravity.x, "gravity", false);
  b.number(spec.gravity.y, "gravity", false);
  for (int k = 0; k < nb; ++k) {
    const std::string item = "body '" + m.bodies[k].name + "'";
    const BodyMass none;
    const BodyMass& bm = k < static_cast<int>(spec.bodies.size()) ? spec.bodies[k] : none;
    b.number(bm.mass, item + " mass", true);
    b.number(bm.inertia, item + " inertia", true);
    f.exact.mass.push_back(b.exact(bm.mass, item + " mass"));
    f.exact.inertia.push_back(b.exact(bm.inertia, item + " inertia"));
    f.exact.com.push_back(b.exact(bm.com, item + " com"));
    const ex mass = b.parse(bm.mass, Scope::kGeometry, item + " mass");
    const Vec com = b.vec(bm.com, Scope::kGeometry, item + " com");
    f.symbolic.mass.push_back(mass);
    f.symbolic.inertia.push_back(b.parse(bm.inertia, Scope::kGeometry, item + " inertia"));
    f.symbolic.com.push_back({com.x, com.y});
    b.add_force(f.applied, k, com, mass * g.x, mass * g.y);
    const Vec r = b.point(k, com);
    f.potential -= mass * (g.x * r.x + g.y * r.y);
  }
  for (const Load& load : spec.loads)  // a damper's rates differentiate its ends
    symbolic_detail::naming_errors(m, load.item, load.loc, "its rates cannot be formed",
                                   [&] { add_load(b, load, f); });
  for (const Load& load : spec.loads)
    for (const Expr* e :
         {&load.stiffness, &load.damping, &load.length0, &load.preload, &load.angle0})
      if (!e->text.empty()) b.number(*e, load.item, false);
  f.row_begin.push_back(0);
  for (const Constraint* c : m.constraints()) {
    f.exact.si.push_back(b.exact(reaction_point(*c, c->kind->reaction_i), c->item + " si"));
    f.exact.sj.push_back(b.exact(reaction_point(*c, c->kind->reaction_j), c->item + " sj"));
    for (const auto& [point, to] : {std::pair{c->kind->reaction_i, &f.symbolic.si},
                                    std::pair{c->kind->reaction_j, &f.symbolic.sj}}) {
      const Vec v = b.vec(reaction_point(*c, point), Scope::kGeometry, c->item);
      to->push_back({v.x, v.y});
    }
    f.row_begin.push_back(f.row_begin.back() + c->equation_count());
  }
  const auto to_d = [](const std::vector<ex>& v) {
    std::vector<double> r;
    for (const ex& e : v) r.push_back(to_double(e));
    return r;
  };
  const auto to_d2 = [](const std::vector<std::array<ex, 2>>& v) {
    std::vector<std::array<double, 2>> r;
    for (const auto& e : v) r.push_back({to_double(e[0]), to_double(e[1])});
    return r;
  };
  f.numbers = {to_d(f.exact.mass), to_d(f.exact.inertia), to_d2(f.exact.com), to_d2(f.exact.si),
               to_d2(f.exact.sj)};
  return f;
}

bool has_force_input(const ForceSpec& spec) {
  const auto given = [](const Expr& e) { return e.text != "0"; };
  if (!spec.loads.empty() || given(spec.gravity.x) || given(spec.gravity.y)) return true;
  for (const BodyMass& b : spec.bodies)
    for (const Expr* e : {&b.mass, &b.inertia, &b.com.x, &b.com.y})
      if (given(*e)) return true;
  return false;
}

namespace {
std::string label(const Constraint& c, const char* kind, int k) {
  return c.name.empty() ? std::string(kind) + std::to_string(k) : c.name;
}
}  // namespace

std::vector<std::string> force_columns(const Mechanism& m) {
  std::vector<std::string> names;
  for (std::size_t d = 0; d < m.drivers.size(); ++d) {
    const Constraint& c = m.drivers[d];
    if (c.free) continue;  // moved by the forces: no actuator, no effort
    const std::string base = label(c, "driver", static_cast<int>(d));
    if (!c.kind->reaction) {
      for (int e = 0; e < c.equation_count(); ++e)
        names.push_back(base + ".effort" + std::to_string(e));
    } else {
      names.push_back(base + ".effort");
    }
  }
  for (std::size_t j = 0; j < m.joints.size(); ++j) {
    const Constraint& c = m.joints[j];
    if (!c.kind->reaction) continue;
    const std::string base = label(c, "joint", static_cast<int>(j));
    for (const char* part : {".fx", ".fy", ".tz"}) names.push_back(base + part);
    if (c.kind->normal_force) names.push_back(base + ".fn");
  }
  return names;
}

bool is_distance(const Constraint& c) { return c.kind->squared_distance; }
bool is_expression(const Constraint& c) { return !c.kind->reaction; }

}  // namespace kinegen::codegen
