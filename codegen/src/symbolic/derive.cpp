// derive: the symbolic model of a mechanism: the parameters' values, Phi and its derivatives
// (Phi_q, nu, gamma), q0, points, outputs and the coordinates' tolerance scales.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/symbolic/forces.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"
#include "symbolic_detail.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

using namespace symbolic_detail;

namespace {

// q0 and point offsets: constants of the geometry (the constraints' own values are read by
// their kinds through EquationContext).
class Builder {
 public:
  Builder(const Mechanism& m, const SymbolTable& s, const std::vector<GiNaC::numeric>& values)
      : m_(m), s_(s), values_(values) {}

  std::pair<ex, ex> vec(const Vec2& v, const std::string& item) const {
    return {geometry(v.x, item), geometry(v.y, item)};
  }

  // A constant of the geometry, checked to evaluate to a finite number.
  ex geometry(const Expr& e, const std::string& item) const {
    return geometry_value(m_, s_, values_, e, item);
  }

  std::vector<ex> equations(const Constraint& c) const {
    return c.kind->equations(EquationContext(c, m_, s_, values_));
  }

 private:
  const Mechanism& m_;
  const SymbolTable& s_;
  const std::vector<GiNaC::numeric>& values_;
};

std::vector<GiNaC::numeric> parameter_values(const Mechanism& m, const SymbolTable& s,
                                             const std::vector<ParamOverride>& overrides) {
  std::vector<GiNaC::numeric> values;
  const auto constant = [&](const Expr& e, const std::string& item) {
    const ex exact = s.parse(e, Scope::kConstant, item);
    // Exact values stay exact; anything irrational (pi, sqrt(2)) is taken at 40 digits.
    const DigitsGuard digits(kEvalDigits);
    ex v;
    try {
      v = GiNaC::is_a<GiNaC::numeric>(exact) ? exact : GiNaC::evalf(exact);
    } catch (const std::exception& err) {
      throw InputError(m.source, item, e.loc,
                       "'" + e.text + "' cannot be evaluated: " + clean_message(err.what()));
    }
    if (!GiNaC::is_a<GiNaC::numeric>(v) || !GiNaC::ex_to<GiNaC::numeric>(v).is_real())
      throw InputError(m.source, item, e.loc, "'" + e.text + "' is not a real number");
    return GiNaC::ex_to<GiNaC::numeric>(v);
  };
  // The base parameters (SymbolTable order): the file's constant, or the override's.
  std::vector<const ParamOverride*> given(s.num_params(), nullptr);
  for (const auto& o : overrides) {
    const auto it = std::find_if(m.parameters.begin(), m.parameters.end(),
                                 [&](const Parameter& p) { return p.name == o.name; });
    if (it == m.parameters.end())
      throw InputError(m.source, "--param " + o.name, {}, "the mechanism has no such parameter");
    const int k = s.find_param(o.name);
    if (k < 0)  // the table was built without this override
      throw std::logic_error("parameter_values: '" + o.name + "' is not a base parameter");
    given[k] = &o;
  }
  for (int k = 0; k < s.num_params(); ++k) {
    const Parameter& p = m.parameters[s.param_source(k)];
    values.push_back(given[k] ? GiNaC::numeric(0) : constant(p.value, "parameters." + p.name));
  }
  std::set<std::size_t> overridden;
  for (const auto& o : overrides) {
    // YAML's special floats are not numbers to the expression reader; say so plainly.
    std::string bare = o.value.substr(o.value[0] == '+' || o.value[0] == '-' ? 1 : 0);
    for (char& ch : bare) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (bare == ".nan" || bare == ".inf" || bare == "nan" || bare == "inf" || bare == "infinity")
      throw InputError(m.source, "--param " + o.name, {},
                       "'" + o.value + "' is not a finite number");
    const std::size_t k = static_cast<std::size_t>(s.find_param(o.name));
    values[k] = constant(Expr{o.value, {}}, "--param " + o.name);
    overridden.insert(k);
  }
  // An overridden value is the option's fault, not the file's.
  for (std::size_t k = 0; k < values.size(); ++k) {
    const Parameter& p = m.parameters[s.param_source(static_cast<int>(k))];
    if (!std::isfinite(values[k].to_double()))
      throw overridden.count(k)
          ? InputError(m.source, "--param " + p.name, {}, "the value is not a finite number")
          : InputError(m.source, "parameters." + p.name, p.loc, "the value is not a finite number");
  }
  // A derived parameter must come out a finite real number from the base values.
  for (const DerivedParameter& d : s.derived_params()) {
    const Parameter& p = m.parameters[d.source];
    double v = 0;
    try {
      v = to_double(substitute_params(d.value, s, values));
    } catch (const std::exception&) {
      v = std::numeric_limits<double>::quiet_NaN();
    }
    if (!std::isfinite(v))
      throw InputError(
          m.source, "parameters." + p.name, p.loc,
          "'" + p.value.text + "' is not a finite real number with the parameters' values");
  }
  return values;
}

// The coordinates (or with kQd, the velocities) `e` reads, ascending.
std::vector<int> coordinates_in(const ex& e, const SymbolTable& s, InputKind kind = InputKind::kQ) {
  std::vector<int> coords;
  for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it)
    if (GiNaC::is_a<GiNaC::symbol>(*it)) {
      const Input in = s.classify(*it);
      if (in.kind == kind) coords.push_back(in.index);
    }
  std::sort(coords.begin(), coords.end());
  coords.erase(std::unique(coords.begin(), coords.end()), coords.end());
  return coords;
}

// The size a coordinate's tolerance scales with. `length`: the scale of its body, or for an
// extra coordinate of kind length, the mechanism's. Angles are in radians and scalars
// (curve parameters and the like) are taken as they are.
double scale_of(CoordinateKind kind, double length) {
  return kind == CoordinateKind::kLength ? length : 1.0;
}

}  // namespace

namespace {

// Every derivative's size is estimated before it is computed (tree_size); one too large, or
// a model whose derivatives together are, is refused with the constraint it comes from.
class Differentiator {
 public:
  Differentiator(const Mechanism& m, const SymbolicModel& model) : m_(m), model_(model) {}

  ex operator()(const ex& e, const GiNaC::symbol& x, int r) {
    const double size = tree_size(e, x).derivative;
    derived_ += size;
    const Constraint& c = *model_.rows[r].constraint;
    const SourceLoc loc = row_loc(c, model_.rows[r].component);
    if (size > kMaxDerivativeSize || derived_ > kMaxDerivedSize) {
      throw InputError(
          m_.source, c.item, loc,
          "its derivatives would grow to about " + short_value(size) + " nodes" +
              (size > kMaxDerivativeSize
                   ? ""
                   : " (with the earlier rows' " + short_value(derived_) + ")") +
              ", beyond the limit of " +
              short_value(size > kMaxDerivativeSize ? kMaxDerivativeSize : kMaxDerivedSize) +
              "; write the expression more compactly");
    }
    return naming_errors(m_, c.item, loc, "cannot be differentiated by " + x.get_name(),
                         [&] { return e.diff(x); });
  }

 private:
  const Mechanism& m_;
  const SymbolicModel& model_;
  double derived_ = 0;
};

// Phi_q, nu and gamma from Phi.
void derive_rates(const Mechanism& m, const SymbolTable& s, SymbolicModel& model) {
  const int nc = static_cast<int>(model.phi.size());
  Differentiator diff(m, model);
  // Each row is differentiated only by the coordinates it reads (a joint reads at most two
  // bodies): derivation stays linear in the size of the mechanism. Derivatives read no
  // coordinate their expression does not, so w = Phi_q qd below needs no others either.
  std::vector<std::vector<int>> row_coords(nc);
  std::vector<std::size_t> row_begin(nc + 1, 0);  // row r's entries: [row_begin[r], row_begin[r+1])
  for (int r = 0; r < nc; ++r) {
    interruption_point();
    row_coords[r] = coordinates_in(model.phi[r], s);
    row_begin[r] = model.phi_q.size();
    for (int k : row_coords[r]) {
      const ex d = diff(model.phi[r], s.q(k), r);
      if (!d.is_zero()) model.phi_q.push_back({r, k, d});
    }
  }
  row_begin[nc] = model.phi_q.size();

  // nu = -Phi_t. gamma = -((Phi_q qd)_q qd + 2 Phi_qt qd + Phi_tt), collected on the products
  // of velocities as a hand derivation writes it: the coefficient of qd_i qd_k is
  // Phi_{q_i q_k} (i = k) or 2 Phi_{q_i q_k} (i < k, the symmetric pair at once).
  for (int r = 0; r < nc; ++r) {
    interruption_point();
    const ex phi_t = diff(model.phi[r], s.t(), r);
    model.nu.push_back(-phi_t);
    ex quadratic = 0, mixed = 0;
    for (std::size_t e = row_begin[r]; e < row_begin[r + 1]; ++e) {
      const int i = model.phi_q[e].col;
      const ex& entry = model.phi_q[e].value;
      for (int k : row_coords[r]) {
        if (k < i) continue;
        const ex d = diff(entry, s.q(k), r);
        if (!d.is_zero()) quadratic += (k == i ? d : 2 * d) * s.qd(i) * s.qd(k);
      }
      mixed += diff(entry, s.t(), r) * s.qd(i);
    }
    model.gamma.push_back(-(quadratic + 2 * mixed + diff(phi_t, s.t(), r)));
  }
}

// q0 and the points' offsets, and the check that every extra coordinate is read.
void derive_geometry(const Mechanism& m, const SymbolTable& s, const Builder& builder,
                     SymbolicModel& model) {
  for (std::size_t k = 0; k < m.bodies.size(); ++k) {
    const Body& b = m.bodies[k];
    if (m.spatial) {
      for (const ex& e : spatial_q0(m, s, model.param_values, static_cast<int>(k)))
        model.q0.push_back(e);
      continue;
    }
    const std::string item = "body '" + b.name + "' q0";
    for (int c = 0; c < 3; ++c) model.q0.push_back(builder.geometry(b.q0[c], item));
  }
  for (const auto& c : m.coordinates)
    model.q0.push_back(builder.geometry(c.q0, "coordinate '" + c.name + "' q0"));
  // An extra coordinate that no equation reads would leave a zero column in Phi_q.
  {
    std::vector<bool> used(s.nq(), false);
    for (const auto& e : model.phi_q) used[e.col] = true;
    for (std::size_t k = 0; k < m.coordinates.size(); ++k)
      if (!used[m.coordinate_index(static_cast<int>(k))])
        throw InputError(m.source, "coordinate '" + m.coordinates[k].name + "'",
                         m.coordinates[k].loc,
                         "no joint or driver equation uses it, so the system would be singular "
                         "(use it in an equation or a curve, or remove it)");
  }
  for (const auto& p : m.points)
    model.point_s.push_back(builder.vec(p.s, "point '" + p.name + "' s"));
  if (!m.spatial) return;
  for (const auto& p : m.points)
    model.point_s3.push_back({model.point_s[model.point_s3.size()].first,
                              model.point_s[model.point_s3.size()].second,
                              builder.geometry(p.s.z, "point '" + p.name + "' s")});
  for (const auto& v : m.vectors) {
    const std::string item = "vector '" + v.name + "' v";
    model.vectors3.push_back(
        {builder.geometry(v.s.x, item), builder.geometry(v.s.y, item), builder.geometry(v.s.z, item)});
  }
}

// The outputs: values, rates, accelerations at qdd = 0 and O_q; for an output that reads
// velocities (as a load may), the rate at qdd = 0 and O_qd instead of an acceleration.
void derive_outputs(const Mechanism& m, SymbolTable& s, SymbolicModel& model) {
  std::vector<ex> by_qd;
  bool any_velocity = false;
  if (m.spatial) define_spatial_names(m, s, model);
  for (const auto& o : m.outputs) {
    const Expr text = m.spatial ? spatial_output_text(m, o.value) : o.value;
    const ex value = s.parse(text, Scope::kLoad, "outputs." + o.name);
    const std::vector<int> coords = coordinates_in(value, s);
    std::vector<ex> grad(s.nq(), ex(0)), grad_qd(s.nq(), ex(0));
    ex rate = value.diff(s.t());
    const std::vector<int> velocities = coordinates_in(value, s, InputKind::kQd);
    const bool reads_velocity = !velocities.empty();
    for (int k : velocities) grad_qd[k] = value.diff(s.qd(k));
    for (int k : coords) {
      grad[k] = value.diff(s.q(k));
      rate += grad[k] * s.qd(k);
    }
    // The rate reads only the coordinates the value does, and qd.
    ex a0 = 0;
    if (!reads_velocity) {
      a0 = rate.diff(s.t());
      for (int k : coords) a0 += rate.diff(s.q(k)) * s.qd(k);
    }
    any_velocity = any_velocity || reads_velocity;
    model.output_values.push_back(value);
    model.output_rates.push_back(rate);
    model.output_a0.push_back(a0);
    model.output_q.insert(model.output_q.end(), grad.begin(), grad.end());
    model.output_reads_velocity.push_back(reads_velocity);
    by_qd.insert(by_qd.end(), grad_qd.begin(), grad_qd.end());
  }
  if (any_velocity) model.output_qd = std::move(by_qd);
}

// Names each free coordinate's value Z and rate Z_d for the expressions parsed after it
// (outputs here; loads and stop_when later).
void define_free_names(const Mechanism& m, SymbolTable& s, const SymbolicModel& model) {
  const std::vector<int> free = m.free_drivers();
  for (std::size_t k = 0; k < free.size(); ++k) {
    const std::string& name = m.drivers[free[k]].name;
    s.define(name, model.free_values[k]);
    s.define(name + "_d", model.free_rates[k]);
  }
}

// Tolerance scales: a body's x and y scale with the geometry of its own joints and drivers
// (the local vectors on it, a distance joint's length), so a 1e-6 follower next to a 1e6 arm
// keeps its own accuracy. q0, reported points and ground anchors never enter: they do not
// set how precisely a link must close. A body without such geometry (a slider pinned at its
// origin) takes the largest of the bodies joined to it, else the largest body scale; a
// mechanism without any, 1.
std::vector<double> body_scales(const Mechanism& m, const SymbolTable& s, const Builder& builder,
                                const std::vector<GiNaC::numeric>& values) {
  std::vector<double> body_scale(m.bodies.size(), 0.0);
  const auto grow = [&](int body, const ex& e) {
    if (body == kGround) return;
    const double v = std::abs(to_double(substitute_params(e, s, values)));
    if (std::isfinite(v)) body_scale[body] = std::max(body_scale[body], v);
  };
  for (const auto* c : m.constraints()) {
    for (const auto& [body, v] : offsets(*c)) {
      if (v->x.text.empty()) continue;  // a spatial default computed at the q0 pose
      const auto lv = builder.vec(*v, c->item);
      grow(body, lv.first);
      grow(body, lv.second);
      if (m.spatial && !v->z.text.empty()) grow(body, builder.geometry(v->z, c->item));
    }
    if (c->kind->squared_distance && !c->is_driver) {
      const ex length = builder.geometry(c->value, c->item + " value");
      grow(c->i, length);
      grow(c->j, length);
    }
  }
  return body_scale;
}

// The mechanism's length scale: the largest body scale, 1 without any.
double length_scale_of(const std::vector<double>& body_scale) {
  double largest = 0;
  for (double v : body_scale) largest = std::max(largest, v);
  return largest > 0 ? largest : 1.0;
}

void derive_scales(const Mechanism& m, const std::vector<double>& body_scale,
                   SymbolicModel& model) {
  const int num_bodies = static_cast<int>(m.bodies.size());
  model.length_scale = length_scale_of(body_scale);
  // A body without geometry of its own moves with the bodies it is joined to.
  std::vector<double> joined(num_bodies, 0.0);
  for (const auto* c : m.constraints())
    if (c->i != kGround && c->j != kGround) {
      joined[c->i] = std::max(joined[c->i], body_scale[c->j]);
      joined[c->j] = std::max(joined[c->j], body_scale[c->i]);
    }
  for (int b = 0; b < num_bodies; ++b) {
    const double length = body_scale[b] > 0 ? body_scale[b]
                          : joined[b] > 0   ? joined[b]
                                            : model.length_scale;
    // Spatial: x, y, z, then the Euler parameters (unit quaternions: scale 1).
    const std::vector<CoordinateKind> kinds =
        m.spatial ? std::vector<CoordinateKind>(3, CoordinateKind::kLength)
                  : std::vector<CoordinateKind>{CoordinateKind::kLength, CoordinateKind::kLength,
                                                CoordinateKind::kAngle};
    std::vector<CoordinateKind> all = kinds;
    if (m.spatial) all.insert(all.end(), 4, CoordinateKind::kScalar);
    for (auto kind : all) {
      model.coordinate_kinds.push_back(kind);
      model.coordinate_scales.push_back(scale_of(kind, length));
    }
  }
  for (const auto& c : m.coordinates) {
    model.coordinate_kinds.push_back(c.kind);
    model.coordinate_scales.push_back(scale_of(c.kind, model.length_scale));
  }
}

// The quantity each free coordinate measures: its row of Phi with the input at 0,
// g(q) - z for the angle and position types, |d|^2 - z^2 for distance; and its rate.
void derive_free_values(const Mechanism& m, const SymbolTable& s, SymbolicModel& model) {
  for (int d : m.free_drivers()) {
    const Constraint& c = m.drivers[d];
    ex g;
    for (std::size_t r = 0; r < model.rows.size(); ++r)
      if (model.rows[r].constraint == &c) g = model.phi[r];
    g = g.subs(kinegen_input(d, 0, s.t()) == 0);
    if (is_distance(c)) g = sqrt(g);
    ex rate = 0;
    for (int k = 0; k < s.nq(); ++k) rate += g.diff(s.q(k)) * s.qd(k);
    model.free_values.push_back(g);
    model.free_rates.push_back(rate);
  }
}

}  // namespace

SymbolicModel derive(const Mechanism& m, SymbolTable& s,
                     const std::vector<ParamOverride>& overrides) {
  SymbolicModel model;
  model.param_values = parameter_values(m, s, overrides);
  const Builder builder(m, s, model.param_values);
  if (m.suspension) model.design_t = check_suspension(m, s, model.param_values);

  for (const auto* c : m.constraints()) {
    const auto rows = builder.equations(*c);
    for (std::size_t k = 0; k < rows.size(); ++k) {
      model.phi.push_back(rows[k]);
      model.rows.push_back({c, static_cast<int>(k)});
    }
  }
  // Where no row is at hand to name (an output's or a free item's value), the file.
  naming_errors(m, "file", {}, "the derivatives cannot be formed", [&] {
    derive_free_values(m, s, model);
    derive_rates(m, s, model);
    derive_geometry(m, s, builder, model);
    define_free_names(m, s, model);
    derive_outputs(m, s, model);
  });
  derive_scales(m, body_scales(m, s, builder, model.param_values), model);
  // The laws' boundaries, once the length scale is known: a driven length's jumps are
  // measured against it (the equations above took the laws unchecked).
  model.warnings = driver_law_warnings(m, s, model.param_values, model.length_scale);
  return model;
}

}  // namespace kinegen::codegen
