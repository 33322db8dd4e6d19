#include "kinegen/codegen/symbolic.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <set>

#include "kinegen/codegen/constraints.hpp"
#include "kinegen/codegen/functions.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

namespace {

// The functions the format allows (functions.hpp), looked up in GiNaC's own reader table.
GiNaC::prototype_table allowed_functions() {
  GiNaC::prototype_table table;
  for (const auto& [proto, reader] : GiNaC::get_default_reader())
    if (find_math_function(proto.first) && proto.second == 1) table[proto] = reader;
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

// A constant of the geometry, checked to evaluate to a finite number.
void check_finite(const Mechanism& m, const SymbolTable& s,
                  const std::vector<GiNaC::numeric>& values, const ex& value, const Expr& e,
                  const std::string& item) {
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

}  // namespace

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
  codegen::check_finite(m_, s_, values_, value, e, item);
}

// An expression in t or q with the parameters put in: no division by zero appears, and every
// number in it is finite (1e999 * t is not).
void EquationContext::check_defined(const ex& value, const Expr& e, const std::string& item) const {
  try {
    const ex v = substitute_params(value, s_, values_);
    for (auto it = v.preorder_begin(); it != v.preorder_end(); ++it)
      if (GiNaC::is_a<GiNaC::numeric>(*it) &&
          !std::isfinite(GiNaC::ex_to<GiNaC::numeric>(*it).to_double()))
        throw InputError(m_.source, item, e.loc,
                         "'" + e.text + "' holds a number that is not finite");
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& err) {
    throw InputError(m_.source, item, e.loc,
                     "'" + e.text + "' cannot be evaluated: " + clean_message(err.what()));
  }
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
  if (to_double(substitute_params(GiNaC::pow(v.first, 2) + GiNaC::pow(v.second, 2), s_, values_)) ==
      0.0)
    throw InputError(m_.source, c_.item, c_.vector("vi").x.loc, "vi must not be the zero vector");
  const Vec av = rotate(frame_i().phi, v);
  return -av.second * d.first + av.first * d.second;
}

ex EquationContext::value() const {
  const std::string item = c_.item + (c_.is_driver ? " f" : " value");
  const ex v = s_.parse(c_.value, c_.is_driver ? Scope::kDriverTime : Scope::kGeometry, item);
  if (!c_.is_driver) check_finite(v, c_.value, item);
  if (c_.is_driver) check_defined(v, c_.value, item);
  return v;
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

  double scale = 0;
  const auto grow = [&](const ex& e) {
    scale = std::max(scale, std::abs(to_double(substitute_params(e, s, model.param_values))));
  };
  for (const auto& b : m.bodies) {
    const std::string item = "body '" + b.name + "' q0";
    for (int c = 0; c < 3; ++c) {
      model.q0.push_back(builder.geometry(b.q0[c], item));
      if (c < 2) grow(model.q0.back());
    }
  }
  for (const auto& p : m.points) {
    const auto v = builder.vec(p.s, "point '" + p.name + "' s");
    model.point_s.push_back(v);
    grow(v.first);
    grow(v.second);
  }
  for (const auto* c : m.constraints()) {
    for (const Vec2* v : offsets(*c)) {
      const auto lv = builder.vec(*v, c->item);
      grow(lv.first);
      grow(lv.second);
    }
  }
  model.length_scale = scale > 0 ? scale : 1.0;
  return model;
}

}  // namespace kinegen::codegen
