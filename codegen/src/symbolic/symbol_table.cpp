// The symbol table: every GiNaC symbol of a model (coordinates, velocities, t, parameters,
// definitions) and the reader of the format's expressions in their scopes.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "kinegen/codegen/symbolic/functions.hpp"
#include "symbolic_detail.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

using namespace symbolic_detail;

namespace {

// atan2(y, x) as its half-angle form 2 atan(y / (sqrt(x^2 + y^2) + x)): the angle of (x, y) in
// (-pi, pi], built from the functions every stage lowers (singular only on the negative x
// axis, where atan2 jumps). Aligned as read_law in functions.cpp: GiNaC tells readers from
// function serials by their lowest bit.
[[gnu::aligned(16)]] ex read_atan2(const GiNaC::exvector& args) {
  const ex &y = args[0], &x = args[1];
  // On the x axis itself the form gives 0 for every x: pi on its negative half.
  if (y.is_zero()) return GiNaC::Pi * (1 - x / GiNaC::sqrt(x * x)) / 2;
  return 2 * GiNaC::atan(y / (GiNaC::sqrt(x * x + y * y) + x));
}

// The prefixes of a body's coordinates' names: x_, y_, phi_ (spatial: x_ ... e3_).
std::vector<const char*> body_prefixes(const Mechanism& m) {
  if (m.spatial) return {"x_", "y_", "z_", "e0_", "e1_", "e2_", "e3_"};
  return {"x_", "y_", "phi_"};
}

// The names loads use for rates: xd_<body>, yd_<body>, phid_<body> (spatial: zd_, e0d_ ...),
// <coordinate>_d.
void name_rates(const Mechanism& m, const std::vector<const char*>& prefixes,
                const std::vector<GiNaC::realsymbol>& qd, std::map<std::string, ex>& names) {
  const std::size_t per_body = prefixes.size();
  for (std::size_t b = 0; b < m.bodies.size(); ++b)
    for (std::size_t c = 0; c < per_body; ++c) {
      const std::string prefix = prefixes[c];
      names[prefix.substr(0, prefix.size() - 1) + "d_" + m.bodies[b].name] = qd[per_body * b + c];
    }
  for (std::size_t c = 0; c < m.coordinates.size(); ++c)
    names[m.coordinates[c].name + "_d"] = qd[per_body * m.bodies.size() + c];
}

// The functions the format allows (functions.hpp), looked up in GiNaC's own reader table.
GiNaC::prototype_table allowed_functions() {
  GiNaC::prototype_table table;
  for (const auto& [proto, reader] : GiNaC::get_default_reader())
    if (find_math_function(proto.first) && proto.second == 1) table[proto] = reader;
  add_motion_law_readers(table);
  table[{"atan2", 2}] = read_atan2;
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

bool scope_allows(Scope scope, InputKind kind) {
  switch (kind) {
    case InputKind::kParam:
      return scope != Scope::kConstant;
    case InputKind::kQ:
      return scope == Scope::kJoint || scope == Scope::kDriver || scope == Scope::kLoad;
    case InputKind::kT:
      return scope == Scope::kDriverTime || scope == Scope::kDriver || scope == Scope::kLoad;
    case InputKind::kQd:
      return scope == Scope::kLoad;
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
    case Scope::kLoad:
      return "not allowed here";
  }
  return "";
}

// Why a velocity may not be used, for the item that uses one (its name says what it is).
std::string velocity_hint(const std::string& item) {
  if (item.rfind("forces[", 0) == 0)
    return "only a force's f and a torque's value may use velocities (xd_<body>, yd_<body>, "
           "phid_<body>, <name>_d); a spring-damper's damping gives its own";
  return "expressions may not use velocities; they follow from the positions";
}

// The edit distance of a and b (insertions, deletions, substitutions and swaps of neighbours).
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1,
                          d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

// The position coordinate a velocity-like name stands for the rate of (omega_B, v_B, vx_B,
// alpha_B, ... of body B; C_dot, C_v of coordinate C), or "" when it does not read as one.
std::string position_of_rate(const std::string& name,
                             const std::function<bool(const std::string&)>& is_coordinate) {
  struct Prefix {
    const char* prefix;
    const char* coordinate;
  };
  static const Prefix kPrefixes[] = {
      {"omega_", "phi_"}, {"alpha_", "phi_"},  {"w_", "phi_"},   {"dphi_", "phi_"},
      {"ddphi_", "phi_"}, {"phidot_", "phi_"}, {"phidd_", "phi_"}, {"v_", "x_"},
      {"vx_", "x_"},      {"xdot_", "x_"},     {"xdd_", "x_"},   {"a_", "x_"},
      {"ax_", "x_"},      {"vy_", "y_"},       {"ydot_", "y_"},  {"ydd_", "y_"},
      {"ay_", "y_"}};
  for (const Prefix& p : kPrefixes) {
    const std::string prefix = p.prefix;
    if (name.size() > prefix.size() && name.rfind(prefix, 0) == 0) {
      const std::string position = p.coordinate + name.substr(prefix.size());
      if (is_coordinate(position)) return position;
    }
  }
  for (const char* suffix : {"_dot", "_ddot", "_dd", "_d", "_v", "_a", "_omega", "_alpha"}) {
    const std::string s = suffix;
    if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0 &&
        is_coordinate(name.substr(0, name.size() - s.size())))
      return name.substr(0, name.size() - s.size());
  }
  return "";
}

// Whether a name position_of_rate reads as a rate reads as a second derivative (alpha_B,
// ax_B, C_dd, ...): no expression may use those.
bool reads_as_acceleration(const std::string& name) {
  for (const char* prefix : {"alpha_", "ddphi_", "phidd_", "xdd_", "ydd_", "a_", "ax_", "ay_"})
    if (name.rfind(prefix, 0) == 0) return true;
  for (const std::string suffix : {"_ddot", "_dd", "_a", "_alpha"})
    if (name.size() > suffix.size() &&
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0)
      return true;
  return false;
}

}  // namespace

std::string SymbolTable::unknown_symbol_hint(const std::string& name, Scope scope,
                                             const std::string& item) const {
  const auto is_coordinate = [&](const std::string& n) {
    return std::find(coord_names_.begin(), coord_names_.end(), n) != coord_names_.end();
  };
  if (!scope_allows(scope, InputKind::kQd) && scope_allows(scope, InputKind::kQ)) {
    if (const std::string position = position_of_rate(name, is_coordinate); !position.empty())
      return ": it reads as a rate of '" + position + "'; " + velocity_hint(item) +
             " (its position is '" + position + "')";
  }
  if (scope_allows(scope, InputKind::kQd)) {
    // Where velocities are allowed, name the one the format spells.
    if (const std::string position = position_of_rate(name, is_coordinate); !position.empty()) {
      const auto k = std::find(coord_names_.begin(), coord_names_.end(), position);
      const bool acceleration = reads_as_acceleration(name);
      const std::string what = acceleration ? "an acceleration" : "a rate";
      const std::string then = acceleration ? "', which expressions may not use; its velocity is '"
                                            : "', whose velocity is '";
      for (const auto& [candidate, value] : names_)
        if (candidate != position + "_dot" && GiNaC::is_a<GiNaC::symbol>(value) &&
            value.is_equal(qd_[k - coord_names_.begin()]))
          return ": it reads as " + what + " of '" + position + then + candidate + "'";
    }
  }
  // The nearest name the scope allows, within a quarter of the name's length (at least 1).
  std::string best;
  std::size_t best_distance = std::max<std::size_t>(1, name.size() / 4) + 1;
  const auto consider = [&](const std::string& candidate) {
    const std::size_t d = edit_distance(name, candidate);
    if (d < best_distance) best = candidate, best_distance = d;
  };
  for (const auto& [candidate, value] : names_) {
    if (GiNaC::is_a<GiNaC::symbol>(value) && roles_.count(value) &&
        !scope_allows(scope, classify(value).kind))
      continue;
    if (!GiNaC::is_a<GiNaC::symbol>(value) && scope == Scope::kConstant) continue;
    consider(candidate);
  }
  if (scope_allows(scope, InputKind::kT)) consider("t");
  consider("pi");
  if (best.empty()) return "";
  return "; did you mean '" + best + "'?";
}

namespace symbolic_detail {

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

}  // namespace symbolic_detail

SymbolTable::SymbolTable(const Mechanism& m, const std::vector<std::string>& overridden)
    : source_(m.source), t_("t") {
  const std::vector<const char*> prefixes = body_prefixes(m);
  for (const auto& b : m.bodies) {
    for (const char* prefix : prefixes) {
      const std::string name = prefix + b.name;
      coord_names_.push_back(name);
      q_.emplace_back(name);
      qd_.emplace_back(name + "_dot");
    }
  }
  for (const auto& c : m.coordinates) {
    coord_names_.push_back(c.name);
    q_.emplace_back(c.name);
    qd_.emplace_back(c.name + "_dot");
  }
  for (int k = 0; k < nq(); ++k) {
    roles_.emplace(q_[k], Input{InputKind::kQ, k});
    roles_.emplace(qd_[k], Input{InputKind::kQd, k});
  }
  roles_.emplace(t_, Input{InputKind::kT, 0});
  for (int k = 0; k < nq(); ++k) names_[coord_names_[k]] = q_[k];
  // Velocities are known by name only to be refused with a message of their own (scope_allows
  // admits them nowhere), not as an unknown symbol.
  for (int k = 0; k < nq(); ++k) names_[coord_names_[k] + "_dot"] = qd_[k];
  // The names loads use: xd_<body>, yd_<body>, phid_<body>, <coordinate>_d.
  name_rates(m, prefixes, qd_, names_);
  // A name read above its definition is an "unknown symbol" to the parser, which sends the
  // user looking for a typo: say where it is defined instead.
  const auto in_order = [&](const Expr& value, Scope scope, const std::string& item,
                            const std::string& self, bool is_parameter) {
    try {
      return parse(value, scope, item);
    } catch (const InputError& e) {
      const std::string unknown = "unknown symbol '";
      const std::string& detail = e.detail();
      const std::size_t at = detail.find(unknown);
      if (at == std::string::npos) throw;
      const std::size_t from = at + unknown.size();
      const std::string name = detail.substr(from, detail.find('\'', from) - from);
      const int use = value.loc.line;
      std::string why;
      for (const Parameter& p : m.parameters)
        if (p.name == name)
          why = name == self ? "'" + name + "' refers to itself"
                             : name + " is defined at line " + std::to_string(p.loc.line) +
                                   ", after its use at line " + std::to_string(use) +
                                   " (a parameter may use only the parameters above it)";
      for (const Definition& d : m.definitions)
        if (d.name == name)
          why = name == self ? "'" + name + "' refers to itself"
                : is_parameter
                    ? name + " is a definition (line " + std::to_string(d.loc.line) +
                          "), which a parameter cannot use (a parameter may use only the "
                          "parameters above it)"
                    : name + " is defined at line " + std::to_string(d.loc.line) +
                          ", after its use at line " + std::to_string(use) +
                          " (a definition may use only the definitions above it)";
      if (why.empty()) throw;
      throw InputError(source_, e.item(), e.loc(), "cannot read '" + value.text + "': " + why);
    }
  };
  // Parameters in file order, each seeing only the earlier ones: a value that reads another
  // parameter makes a derived one (unless --param overrides it, which drops the formula).
  params_.reserve(m.parameters.size());
  for (std::size_t i = 0; i < m.parameters.size(); ++i) {
    const Parameter& p = m.parameters[i];
    const bool forced = std::find(overridden.begin(), overridden.end(), p.name) != overridden.end();
    if (!forced) {
      const ex value = in_order(p.value, Scope::kGeometry, "parameters." + p.name, p.name, true);
      if (!value.info(GiNaC::info_flags::numeric) && has_symbol(value)) {
        derived_.push_back({p.name, static_cast<int>(i), value});
        names_[p.name] = value;
        continue;
      }
    }
    const int k = num_params();
    param_names_.push_back(p.name);
    params_.emplace_back(p.name);
    param_source_.push_back(static_cast<int>(i));
    roles_.emplace(params_[k], Input{InputKind::kParam, k});
    names_[p.name] = params_[k];
  }
  // Definitions, in order, each in the names before it; a context's restrictions apply to
  // what a definition stands for (parse checks the substituted expression).
  for (const Definition& d : m.definitions)
    names_[d.name] = in_order(d.value, Scope::kDriver, "definitions." + d.name, d.name, false);
}

bool SymbolTable::has_symbol(const ex& e) {
  for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it)
    if (GiNaC::is_a<GiNaC::symbol>(*it)) return true;
  return false;
}

int SymbolTable::find_param(const std::string& name) const {
  for (int k = 0; k < num_params(); ++k)
    if (param_names_[k] == name) return k;
  return -1;
}

const DerivedParameter* SymbolTable::find_derived(const std::string& name) const {
  for (const auto& d : derived_)
    if (d.name == name) return &d;
  return nullptr;
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

  try {
    check_text_cost(text);
  } catch (const CostError& err) {
    throw InputError(source_, item, expr.loc, err.what());
  }
  ex e;
  try {
    GiNaC::parser reader(table, /*strict=*/true, kFunctions);
    e = reader(rationalize_literals(expr.text));
  } catch (const std::exception& err) {
    std::string message = clean_message(err.what());
    const std::string unknown = "unknown symbol '";
    if (message.rfind(unknown, 0) == 0)
      message += unknown_symbol_hint(message.substr(unknown.size(), message.size() -
                                                                        unknown.size() - 1),
                                     scope, item);
    throw InputError(source_, item, expr.loc, "cannot read '" + expr.text + "': " + message);
  }
  for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it) {
    if (GiNaC::is_a<GiNaC::symbol>(*it)) {
      const Input role = classify(*it);
      const std::string name = GiNaC::ex_to<GiNaC::symbol>(*it).get_name();
      if (role.kind == InputKind::kQd && !scope_allows(scope, role.kind))
        throw InputError(source_, item, expr.loc,
                         "'" + expr.text + "' uses the velocity '" + name + "': " +
                             velocity_hint(item) + " (its position is '" +
                             coord_names_[role.index] + "')");
      if (!scope_allows(scope, role.kind))
        throw InputError(source_, item, expr.loc,
                         "'" + expr.text + "' uses '" + name + "': " + scope_hint(scope));
    } else if (GiNaC::is_a<GiNaC::numeric>(*it) && !GiNaC::ex_to<GiNaC::numeric>(*it).is_real()) {
      throw InputError(source_, item, expr.loc, "'" + expr.text + "' is not real");
    } else if (GiNaC::is_a<GiNaC::constant>(*it) && !it->is_equal(GiNaC::Pi)) {
      throw InputError(source_, item, expr.loc,
                       "'" + expr.text + "' uses an unknown constant (only pi is known)");
    }
  }
  return e;
}

void SymbolTable::define(const std::string& name, const ex& value) {
  names_.emplace(name, value);
}

int SymbolTable::define_extra(const std::string& name) {
  const int k = static_cast<int>(extra_.size());
  extra_.emplace_back(name);
  roles_.emplace(extra_.back(), Input{InputKind::kParam, num_params() + k});
  names_[name] = extra_.back();
  return k;
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

double to_double(const ex& e) {
  // Enough digits that rounding to double happens once, here.
  const DigitsGuard digits(kEvalDigits);
  const ex v = GiNaC::evalf(e);
  if (!GiNaC::is_a<GiNaC::numeric>(v)) throw std::logic_error("not a constant expression");
  // GiNaC keeps asin(2) as a complex value; taking its real part would hide the mistake.
  if (!GiNaC::ex_to<GiNaC::numeric>(v).is_real()) throw std::domain_error("the value is not real");
  return GiNaC::ex_to<GiNaC::numeric>(v).to_double();
}

}  // namespace kinegen::codegen
