#include "kinegen/codegen/symbolic.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <set>

namespace kinegen::codegen {

using GiNaC::ex;

namespace {

// The functions the format allows, looked up in GiNaC's own reader table.
GiNaC::prototype_table allowed_functions() {
  static const std::set<std::string> kAllowed = {"sin",  "cos", "tan", "asin", "acos",
                                                 "atan", "exp", "log", "sqrt"};
  GiNaC::prototype_table table;
  for (const auto& [proto, reader] : GiNaC::get_default_reader())
    if (kAllowed.count(proto.first) && proto.second == 1) table[proto] = reader;
  return table;
}

// Rewrites decimal literals as exact ratios ("1.25e-1" -> "(125/1000)"), so values are exact
// in the symbolic stage and the high-precision path is not limited to double.
std::string rationalize_literals(const std::string& text) {
  std::string out;
  std::size_t k = 0;
  const auto digit = [&](std::size_t p) {
    return p < text.size() && std::isdigit(static_cast<unsigned char>(text[p]));
  };
  while (k < text.size()) {
    const bool starts_number =
        (digit(k) || (text[k] == '.' && digit(k + 1))) &&
        (k == 0 || !(std::isalnum(static_cast<unsigned char>(text[k - 1])) || text[k - 1] == '_'));
    if (!starts_number) {
      out += text[k++];
      continue;
    }
    std::string mantissa;
    long frac_digits = 0;
    while (digit(k)) mantissa += text[k++];
    if (k < text.size() && text[k] == '.') {
      ++k;
      while (digit(k)) {
        mantissa += text[k++];
        ++frac_digits;
      }
    }
    long exponent = 0;
    if (k < text.size() && (text[k] == 'e' || text[k] == 'E')) {
      std::size_t p = k + 1;
      bool negative = false;
      if (p < text.size() && (text[p] == '+' || text[p] == '-')) negative = text[p++] == '-';
      if (digit(p)) {
        std::string e;
        while (digit(p)) e += text[p++];
        if (e.size() > 6) e = "999999";  // beyond any sensible input; keeps the ratio finite
        exponent = std::stol(e) * (negative ? -1 : 1);
        k = p;
      }
    }
    const long scale = exponent - frac_digits;
    std::string num = mantissa, den = "1";
    if (scale > 0) num += std::string(static_cast<std::size_t>(scale), '0');
    if (scale < 0) den += std::string(static_cast<std::size_t>(-scale), '0');
    out += "(" + num + "/" + den + ")";
  }
  return out;
}

// Cleans GiNaC's messages of their source-location suffixes.
std::string clean_message(const std::string& what) {
  std::string m = what.substr(0, what.find('\n'));
  const std::string parse_prefix = "GiNaC: parse error at line 0, column 0: ";
  if (m.rfind(parse_prefix, 0) == 0) m = m.substr(parse_prefix.size());
  const std::string unknown = "find_or_insert_symbol: symbol \"";
  if (m.rfind(unknown, 0) == 0) {
    const std::string name = m.substr(unknown.size(), m.find('"', unknown.size()) - unknown.size());
    return "unknown symbol '" + name + "'";
  }
  if (m.find("division by zero") != std::string::npos) return "division by zero";
  return m;
}

bool scope_allows(Scope scope, InputKind kind) {
  switch (kind) {
    case InputKind::kParam:
      return scope != Scope::kConstant;
    case InputKind::kQ:
      return scope == Scope::kJoint || scope == Scope::kDriver;
    case InputKind::kT:
      return scope == Scope::kDriverTime || scope == Scope::kDriver;
    case InputKind::kQd:
      return false;
  }
  return false;
}

const char* scope_hint(Scope scope) {
  switch (scope) {
    case Scope::kConstant:
      return "only numbers may be used here";
    case Scope::kGeometry:
      return "only numbers and parameters may be used here";
    case Scope::kJoint:
      return "joints do not depend on t; use a driver";
    case Scope::kDriverTime:
      return "f may use only t and the parameters";
    case Scope::kDriver:
      return "not allowed here";
  }
  return "";
}

}  // namespace

SymbolTable::SymbolTable(const Mechanism& m) : source_(m.source), t_("t") {
  for (const auto& b : m.bodies) {
    for (const char* prefix : {"x_", "y_", "phi_"}) {
      const std::string name = prefix + b.name;
      coord_names_.push_back(name);
      q_.emplace_back(name);
      qd_.emplace_back(name + "_dot");
    }
  }
  for (const auto& p : m.parameters) {
    param_names_.push_back(p.name);
    params_.emplace_back(p.name);
  }
  for (int k = 0; k < nq(); ++k) {
    roles_.emplace(q_[k], Input{InputKind::kQ, k});
    roles_.emplace(qd_[k], Input{InputKind::kQd, k});
  }
  roles_.emplace(t_, Input{InputKind::kT, 0});
  for (int k = 0; k < num_params(); ++k) roles_.emplace(params_[k], Input{InputKind::kParam, k});
  for (int k = 0; k < nq(); ++k) names_[coord_names_[k]] = q_[k];
  for (int k = 0; k < num_params(); ++k) names_[param_names_[k]] = params_[k];
}

ex SymbolTable::parse(const Expr& expr, Scope scope, const std::string& item) const {
  static const GiNaC::prototype_table kFunctions = allowed_functions();
  // Only the names the text may mention go into the parser's table (any run of name
  // characters, from any letter in it): a table of every coordinate, built for each of a
  // large mechanism's expressions, would make reading it quadratic.
  GiNaC::symtab table;
  const std::string& text = expr.text;
  const auto name_char = [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_';
  };
  for (std::size_t k = 0; k < text.size();) {
    if (!name_char(text[k])) {
      ++k;
      continue;
    }
    std::size_t end = k;
    while (end < text.size() && name_char(text[end])) ++end;
    for (std::size_t from = k; from < end; ++from) {
      if (std::isdigit(static_cast<unsigned char>(text[from]))) continue;
      const auto it = names_.find(text.substr(from, end - from));
      if (it != names_.end()) table.insert(*it);
    }
    k = end;
  }
  table["t"] = t_;
  table["pi"] = GiNaC::Pi;

  ex e;
  try {
    GiNaC::parser reader(table, /*strict=*/true, kFunctions);
    e = reader(rationalize_literals(expr.text));
  } catch (const std::exception& err) {
    throw InputError(source_, item, expr.loc,
                     "cannot read '" + expr.text + "': " + clean_message(err.what()));
  }
  for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it) {
    if (GiNaC::is_a<GiNaC::symbol>(*it)) {
      const Input role = classify(*it);
      if (!scope_allows(scope, role.kind))
        throw InputError(source_, item, expr.loc,
                         "'" + expr.text + "' uses '" + GiNaC::ex_to<GiNaC::symbol>(*it).get_name() +
                             "': " + scope_hint(scope));
    } else if (GiNaC::is_a<GiNaC::numeric>(*it) && !GiNaC::ex_to<GiNaC::numeric>(*it).is_real()) {
      throw InputError(source_, item, expr.loc, "'" + expr.text + "' is not real");
    } else if (GiNaC::is_a<GiNaC::constant>(*it) && !it->is_equal(GiNaC::Pi)) {
      throw InputError(source_, item, expr.loc,
                       "'" + expr.text + "' uses an unknown constant (only pi is known)");
    }
  }
  return e;
}

Input SymbolTable::classify(const ex& symbol) const {
  const auto it = roles_.find(symbol);
  if (it == roles_.end()) throw std::logic_error("symbol not created by the symbol table");
  return it->second;
}

ex substitute_params(const ex& e, const SymbolTable& symbols,
                     const std::vector<GiNaC::numeric>& values) {
  GiNaC::exmap map;
  for (int k = 0; k < symbols.num_params(); ++k) map[symbols.param(k)] = values[k];
  return e.subs(map);
}

namespace {
constexpr long kEvalDigits = 40;
}  // namespace

double to_double(const ex& e) {
  // Enough digits that rounding to double happens once, here.
  const DigitsGuard digits(kEvalDigits);
  const ex v = GiNaC::evalf(e);
  if (!GiNaC::is_a<GiNaC::numeric>(v)) throw std::logic_error("not a constant expression");
  // GiNaC keeps asin(2) as a complex value; taking its real part would hide the mistake.
  if (!GiNaC::ex_to<GiNaC::numeric>(v).is_real()) throw std::domain_error("the value is not real");
  return GiNaC::ex_to<GiNaC::numeric>(v).to_double();
}

namespace {

// The library's equations, written once in the notation of the format.
class Builder {
 public:
  Builder(const Mechanism& m, const SymbolTable& s, const std::vector<GiNaC::numeric>& values)
      : m_(m), s_(s), values_(values) {}

  struct Frame {
    ex x, y, phi;
  };

  Frame frame(int body) const {
    if (body == kGround) return {0, 0, 0};
    return {s_.q(3 * body), s_.q(3 * body + 1), s_.q(3 * body + 2)};
  }

  // A(phi) s
  static std::pair<ex, ex> rotate(const ex& phi, const std::pair<ex, ex>& s) {
    return {GiNaC::cos(phi) * s.first - GiNaC::sin(phi) * s.second,
            GiNaC::sin(phi) * s.first + GiNaC::cos(phi) * s.second};
  }

  std::pair<ex, ex> vec(const Vec2& v, const std::string& item) const {
    return {geometry(v.x, item), geometry(v.y, item)};
  }

  // A constant of the geometry, checked to evaluate to a finite number.
  ex geometry(const Expr& e, const std::string& item) const {
    const ex value = s_.parse(e, Scope::kGeometry, item);
    check_finite(value, e, item);
    return value;
  }

  void check_finite(const ex& value, const Expr& e, const std::string& item) const {
    double v = 0;
    try {
      v = to_double(substitute_params(value, s_, values_));
    } catch (const std::exception& err) {
      throw InputError(m_.source, item, e.loc,
                       "'" + e.text + "' cannot be evaluated: " + clean_message(err.what()));
    }
    if (!std::isfinite(v))
      throw InputError(m_.source, item, e.loc, "'" + e.text + "' is not a finite number");
  }

  // An expression in t or q with the parameters put in: no division by zero appears, and every
  // number in it is finite (1e999 * t is not).
  void check_defined(const ex& value, const Expr& e, const std::string& item) const {
    try {
      const ex v = substitute_params(value, s_, values_);
      for (auto it = v.preorder_begin(); it != v.preorder_end(); ++it)
        if (GiNaC::is_a<GiNaC::numeric>(*it) &&
            !std::isfinite(GiNaC::ex_to<GiNaC::numeric>(*it).to_double()))
          throw InputError(m_.source, item, e.loc, "'" + e.text + "' holds a number that is not finite");
    } catch (const InputError&) {
      throw;
    } catch (const std::exception& err) {
      throw InputError(m_.source, item, e.loc,
                       "'" + e.text + "' cannot be evaluated: " + clean_message(err.what()));
    }
  }

  std::vector<ex> equations(const Constraint& c) const {
    const Frame fi = frame(c.i), fj = frame(c.j);
    const auto d_ij = [&] {
      const auto ai = rotate(fi.phi, vec(c.si, c.item + " si"));
      const auto aj = rotate(fj.phi, vec(c.sj, c.item + " sj"));
      return std::pair<ex, ex>{fj.x + aj.first - fi.x - ai.first,
                               fj.y + aj.second - fi.y - ai.second};
    };
    // (A_i vi)^perp . d = -(A_i vi)_y d_x + (A_i vi)_x d_y
    const auto perp_dot = [&](const std::pair<ex, ex>& d) {
      const auto v = vec(c.vi, c.item + " vi");
      if (to_double(substitute_params(GiNaC::pow(v.first, 2) + GiNaC::pow(v.second, 2), s_,
                                      values_)) == 0.0)
        throw InputError(m_.source, c.item, c.vi.x.loc, "vi must not be the zero vector");
      const auto av = rotate(fi.phi, v);
      return -av.second * d.first + av.first * d.second;
    };
    const Scope value_scope = c.is_driver ? Scope::kDriverTime : Scope::kGeometry;
    const auto value = [&] {
      const std::string item = c.item + (c.is_driver ? " f" : " value");
      const ex v = s_.parse(c.value, value_scope, item);
      if (!c.is_driver) check_finite(v, c.value, item);
      if (c.is_driver) check_defined(v, c.value, item);
      return v;
    };
    switch (c.type) {
      case ConstraintType::kRevolute: {
        const auto d = d_ij();
        return {d.first, d.second};
      }
      case ConstraintType::kTranslational: {
        const auto d = d_ij();
        return {perp_dot(d), fj.phi - fi.phi - value()};
      }
      case ConstraintType::kDistance: {
        const auto d = d_ij();
        return {GiNaC::pow(d.first, 2) + GiNaC::pow(d.second, 2) - GiNaC::pow(value(), 2)};
      }
      case ConstraintType::kRevoluteTranslational:
        return {perp_dot(d_ij())};
      case ConstraintType::kAbsoluteX:
        return {fi.x + rotate(fi.phi, vec(c.si, c.item + " s")).first - value()};
      case ConstraintType::kAbsoluteY:
        return {fi.y + rotate(fi.phi, vec(c.si, c.item + " s")).second - value()};
      case ConstraintType::kAbsoluteAngle:
        return {fi.phi - value()};
      case ConstraintType::kRelativeAngle:
        return {fj.phi - fi.phi - value()};
      case ConstraintType::kExpression: {
        std::vector<ex> rows;
        const Scope scope = c.is_driver ? Scope::kDriver : Scope::kJoint;
        for (std::size_t k = 0; k < c.equations.size(); ++k) {
          const std::string item = c.item + " equations[" + std::to_string(k) + "]";
          rows.push_back(s_.parse(c.equations[k], scope, item));
          check_defined(rows.back(), c.equations[k], item);
        }
        return rows;
      }
    }
    return {};
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
  for (const auto& p : m.parameters) values.push_back(constant(p.value, "parameters." + p.name));
  for (const auto& o : overrides) {
    const auto it = std::find_if(m.parameters.begin(), m.parameters.end(),
                                 [&](const Parameter& p) { return p.name == o.name; });
    if (it == m.parameters.end())
      throw InputError(m.source, "--param " + o.name, {}, "the mechanism has no such parameter");
    values[it - m.parameters.begin()] = constant(Expr{o.value, {}}, "--param " + o.name);
  }
  for (std::size_t k = 0; k < values.size(); ++k)
    if (!std::isfinite(values[k].to_double()))
      throw InputError(m.source, "parameters." + m.parameters[k].name, m.parameters[k].loc,
                       "the value is not a finite number");
  return values;
}

// The coordinates `e` reads, ascending.
std::vector<int> coordinates_in(const ex& e, const SymbolTable& s) {
  std::vector<int> coords;
  for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it)
    if (GiNaC::is_a<GiNaC::symbol>(*it)) {
      const Input in = s.classify(*it);
      if (in.kind == InputKind::kQ) coords.push_back(in.index);
    }
  std::sort(coords.begin(), coords.end());
  coords.erase(std::unique(coords.begin(), coords.end()), coords.end());
  return coords;
}

// The size a coordinate's tolerance scales with. `length`: the scale of its body, or for an
// extra coordinate of kind length (spec 6.1), the mechanism's. Angles are in radians and
// scalars (curve parameters and the like) are taken as they are.
double scale_of(CoordinateKind kind, double length) {
  return kind == CoordinateKind::kLength ? length : 1.0;
}

}  // namespace

SymbolicModel derive(const Mechanism& m, const SymbolTable& s,
                     const std::vector<ParamOverride>& overrides) {
  SymbolicModel model;
  model.param_values = parameter_values(m, s, overrides);
  const Builder builder(m, s, model.param_values);

  for (const auto* c : m.constraints()) {
    const auto rows = builder.equations(*c);
    for (std::size_t k = 0; k < rows.size(); ++k) {
      model.phi.push_back(rows[k]);
      model.rows.push_back({c, static_cast<int>(k)});
    }
  }
  const int nc = static_cast<int>(model.phi.size());

  // Each row is differentiated only by the coordinates it reads (a joint reads at most two
  // bodies): derivation stays linear in the size of the mechanism. Derivatives read no
  // coordinate their expression does not, so w = Phi_q qd below needs no others either.
  std::vector<std::vector<int>> row_coords(nc);
  std::vector<std::size_t> row_begin(nc + 1, 0);  // row r's entries: [row_begin[r], row_begin[r+1])
  for (int r = 0; r < nc; ++r) {
    row_coords[r] = coordinates_in(model.phi[r], s);
    row_begin[r] = model.phi_q.size();
    for (int k : row_coords[r]) {
      const ex d = model.phi[r].diff(s.q(k));
      if (!d.is_zero()) model.phi_q.push_back({r, k, d});
    }
  }
  row_begin[nc] = model.phi_q.size();

  // nu = -Phi_t. gamma = -(w_q qd + 2 w_t + Phi_tt), w = Phi_q qd, with w_q qd = sum_k dw/dq_k qd_k.
  for (int r = 0; r < nc; ++r) {
    const ex phi_t = model.phi[r].diff(s.t());
    model.nu.push_back(-phi_t);
    ex w = 0;
    for (std::size_t e = row_begin[r]; e < row_begin[r + 1]; ++e)
      w += model.phi_q[e].value * s.qd(model.phi_q[e].col);
    ex w_q_qd = 0;
    for (int k : row_coords[r]) w_q_qd += w.diff(s.q(k)) * s.qd(k);
    model.gamma.push_back(-(w_q_qd + 2 * w.diff(s.t()) + phi_t.diff(s.t())));
  }

  for (const auto& b : m.bodies) {
    const std::string item = "body '" + b.name + "' q0";
    for (int c = 0; c < 3; ++c) model.q0.push_back(builder.geometry(b.q0[c], item));
  }
  for (const auto& p : m.points)
    model.point_s.push_back(builder.vec(p.s, "point '" + p.name + "' s"));

  // Tolerance scales: a body's x and y scale with the geometry of its own joints and drivers
  // (the local vectors on it, a distance joint's length), so a 1e-6 follower next to a 1e6 arm
  // keeps its own accuracy. q0, reported points and ground anchors never enter: they do not
  // set how precisely a link must close. A body without such geometry (a slider pinned at its
  // origin) takes the largest of the bodies joined to it, else the largest body scale; a
  // mechanism without any, 1.
  const int num_bodies = static_cast<int>(m.bodies.size());
  std::vector<double> body_scale(num_bodies, 0.0);
  const auto grow = [&](int body, const ex& e) {
    if (body == kGround) return;
    const double v = std::abs(to_double(substitute_params(e, s, model.param_values)));
    if (std::isfinite(v)) body_scale[body] = std::max(body_scale[body], v);
  };
  for (const auto* c : m.constraints()) {
    if (c->type == ConstraintType::kExpression) continue;
    for (const auto& [body, v] : {std::pair<int, const Vec2*>{c->i, &c->si}, {c->j, &c->sj}}) {
      const auto lv = builder.vec(*v, c->item);
      grow(body, lv.first);
      grow(body, lv.second);
    }
    if (c->type == ConstraintType::kDistance && !c->is_driver) {
      const ex length = builder.geometry(c->value, c->item + " value");
      grow(c->i, length);
      grow(c->j, length);
    }
  }
  double largest = 0;
  for (double v : body_scale) largest = std::max(largest, v);
  model.length_scale = largest > 0 ? largest : 1.0;
  // A body without geometry of its own moves with the bodies it is joined to.
  std::vector<double> joined(num_bodies, 0.0);
  for (const auto* c : m.constraints())
    if (c->type != ConstraintType::kExpression && c->i != kGround && c->j != kGround) {
      joined[c->i] = std::max(joined[c->i], body_scale[c->j]);
      joined[c->j] = std::max(joined[c->j], body_scale[c->i]);
    }
  for (int b = 0; b < num_bodies; ++b) {
    const double length = body_scale[b] > 0 ? body_scale[b]
                          : joined[b] > 0   ? joined[b]
                                            : model.length_scale;
    for (auto kind : {CoordinateKind::kLength, CoordinateKind::kLength, CoordinateKind::kAngle}) {
      model.coordinate_kinds.push_back(kind);
      model.coordinate_scales.push_back(scale_of(kind, length));
    }
  }
  return model;
}

}  // namespace kinegen::codegen
