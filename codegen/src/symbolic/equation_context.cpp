// EquationContext: what a constraint type (constraints/registry.hpp) reads to write its
// equations: frames, key values parsed in their scopes and checked, curves.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "kinegen/codegen/constraints/registry.hpp"
#include "symbolic_detail.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

using namespace symbolic_detail;

namespace symbolic_detail {

// A constant of the geometry, checked to evaluate to a finite number.
void check_finite(const Mechanism& m, const SymbolTable& s,
                  const std::vector<GiNaC::numeric>& values, const ex& value, const Expr& e,
                  const std::string& item) {
  check_cost(m, s, values, value, e, item);
  double v = 0;
  try {
    v = to_double(substitute_params(value, s, values));
  } catch (const std::exception& err) {
    throw InputError(m.source, item, e.loc,
                     "'" + e.text + "' cannot be evaluated: " + clean_message(err.what()));
  }
  if (!std::isfinite(v))
    throw InputError(m.source, item, e.loc, "'" + e.text + "' is not a finite number");
}

ex geometry_value(const Mechanism& m, const SymbolTable& s,
                  const std::vector<GiNaC::numeric>& values, const Expr& e,
                  const std::string& item) {
  const ex value = s.parse(e, Scope::kGeometry, item);
  check_finite(m, s, values, value, e, item);
  return value;
}

// An expression in t or q with the parameters put in: no division by zero appears, and every
// number in it is finite (1e999 * t is not).
void check_defined_value(const Mechanism& m, const SymbolTable& s,
                         const std::vector<GiNaC::numeric>& values, const ex& value, const Expr& e,
                         const std::string& item) {
  check_cost(m, s, values, value, e, item);
  try {
    const ex v = substitute_params(value, s, values);
    for (auto it = v.preorder_begin(); it != v.preorder_end(); ++it)
      if (GiNaC::is_a<GiNaC::numeric>(*it) &&
          !std::isfinite(GiNaC::ex_to<GiNaC::numeric>(*it).to_double()))
        throw InputError(m.source, item, e.loc,
                         "'" + e.text + "' holds a number that is not finite");
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& err) {
    throw InputError(m.source, item, e.loc,
                     "'" + e.text + "' cannot be evaluated: " + clean_message(err.what()));
  }
}

}  // namespace symbolic_detail

EquationContext::Frame EquationContext::frame(int body) const {
  if (body == kGround) return {0, 0, 0};
  return {s_.q(3 * body), s_.q(3 * body + 1), s_.q(3 * body + 2)};
}

EquationContext::Vec EquationContext::rotate(const ex& phi, const Vec& s) {
  return {GiNaC::cos(phi) * s.first - GiNaC::sin(phi) * s.second,
          GiNaC::sin(phi) * s.first + GiNaC::cos(phi) * s.second};
}

ex EquationContext::geometry(const Expr& e, const std::string& item) const {
  return geometry_value(m_, s_, values_, e, item);
}

void EquationContext::check_finite(const ex& value, const Expr& e, const std::string& item) const {
  symbolic_detail::check_finite(m_, s_, values_, value, e, item);
}

void EquationContext::check_defined(const ex& value, const Expr& e, const std::string& item) const {
  check_defined_value(m_, s_, values_, value, e, item);
}

EquationContext::Vec EquationContext::vector(const std::string& key) const {
  const Vec2& v = c_.vector(key);
  const std::string item = c_.item + " " + key;
  return {geometry(v.x, item), geometry(v.y, item)};
}

EquationContext::Vec EquationContext::d_ij() const {
  const Frame fi = frame_i(), fj = frame_j();
  const Vec ai = rotate(fi.phi, vector("si"));
  const Vec aj = rotate(fj.phi, vector("sj"));
  return {fj.x + aj.first - fi.x - ai.first, fj.y + aj.second - fi.y - ai.second};
}

ex EquationContext::perpendicular(const Vec& d) const {
  const Vec v = vector("vi");
  // Each component on its own: a sum of squares underflows to 0 for vi = [1e-300, 0], which is
  // a direction all the same (its length enters the equations exactly).
  if (number(v.first) == 0.0 && number(v.second) == 0.0)
    throw InputError(m_.source, c_.item, c_.vector("vi").x.loc, "vi must not be the zero vector");
  const Vec av = rotate(frame_i().phi, v);
  return -av.second * d.first + av.first * d.second;
}

ex EquationContext::value() const {
  if (c_.is_driver && !c_.law.plain()) return driver_law(c_, m_, s_, values_);
  const std::string item = c_.item + (c_.is_driver ? " f" : " value");
  const ex v = s_.parse(c_.value, c_.is_driver ? Scope::kDriverTime : Scope::kGeometry, item);
  if (!c_.is_driver) check_finite(v, c_.value, item);
  if (c_.is_driver) check_defined(v, c_.value, item);
  return v;
}

ex EquationContext::scalar(const std::string& key) const {
  return geometry(c_.scalars.at(key), c_.item + " " + key);
}

double EquationContext::number(const ex& e) const {
  return to_double(substitute_params(e, s_, values_));
}

void EquationContext::fail(const std::string& key, const std::string& message) const {
  SourceLoc loc = c_.loc;
  if (const auto it = c_.scalars.find(key); it != c_.scalars.end()) loc = it->second.loc;
  if (const auto it = c_.vectors.find(key); it != c_.vectors.end()) loc = it->second.x.loc;
  throw InputError(m_.source, c_.item, loc, message);
}

std::vector<ex> EquationContext::equations() const {
  std::vector<ex> rows;
  const Scope scope = c_.is_driver ? Scope::kDriver : Scope::kJoint;
  for (std::size_t k = 0; k < c_.equations.size(); ++k) {
    const std::string item = c_.item + " equations[" + std::to_string(k) + "]";
    rows.push_back(s_.parse(c_.equations[k], scope, item));
    check_defined(rows.back(), c_.equations[k], item);
  }
  return rows;
}

ex EquationContext::coordinate(const std::string& key) const {
  return s_.q(m_.coordinate_index(c_.coordinates.at(key)));
}

EquationContext::Vec EquationContext::tangent(const Vec& curve,
                                              const std::string& coordinate_key) const {
  const GiNaC::symbol& u = s_.q(m_.coordinate_index(c_.coordinates.at(coordinate_key)));
  return {curve.first.diff(u), curve.second.diff(u)};
}

EquationContext::Vec EquationContext::curve(const std::string& key,
                                            const std::string& coordinate_key) const {
  const Vec2& v = c_.curves.at(key);
  const Coordinate& q = m_.coordinates[c_.coordinates.at(coordinate_key)];
  const ex u = coordinate(coordinate_key);
  const std::string item = c_.item + " " + key;
  Vec out;
  for (auto [text, to] : {std::pair{&v.x, &out.first}, std::pair{&v.y, &out.second}}) {
    *to = s_.parse(*text, Scope::kDriver, item);
    for (auto it = to->preorder_begin(); it != to->preorder_end(); ++it) {
      if (!GiNaC::is_a<GiNaC::symbol>(*it)) continue;
      const Input in = s_.classify(*it);
      const std::string name = GiNaC::ex_to<GiNaC::symbol>(*it).get_name();
      if (in.kind == InputKind::kT)
        throw InputError(m_.source, item, text->loc,
                         "'" + text->text +
                             "' uses t: a curve is fixed in its body; drive the "
                             "motion with a driver");
      if (in.kind == InputKind::kQ && !it->is_equal(u))
        throw InputError(m_.source, item, text->loc,
                         "'" + text->text + "' uses '" + name +
                             "': a curve may use only its "
                             "coordinate '" +
                             q.name + "', the parameters and definitions");
    }
    check_defined(*to, *text, item);
  }
  // Regular where the mechanism assembles: at the coordinate's q0.
  const Vec d = tangent(out, coordinate_key);
  const ex u0 = geometry(q.q0, "coordinate '" + q.name + "' q0");
  double speed = NAN;
  try {
    const GiNaC::exmap at{{u, u0}};
    speed = std::hypot(number(d.first.subs(at)), number(d.second.subs(at)));
  } catch (const std::exception&) {
  }
  if (!std::isfinite(speed) || speed == 0)
    throw InputError(m_.source, c_.item, v.x.loc,
                     key + " is not regular at " + q.name + " = " + q.q0.text +
                         " (its q0): " + "d" + key + "/d" + q.name +
                         (std::isfinite(speed) ? " = 0" : " is not finite") +
                         ", so the joint's direction there is undefined");
  return out;
}

}  // namespace kinegen::codegen
