// The symbol table: every GiNaC symbol of a model (coordinates, velocities, t, parameters,
// definitions) and the reader of the format's expressions in their scopes.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "kinegen/codegen/symbolic/functions.hpp"
#include "symbolic_detail.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

using namespace symbolic_detail;

namespace {

// The functions the format allows (functions.hpp), looked up in GiNaC's own reader table.
GiNaC::prototype_table allowed_functions() {
  GiNaC::prototype_table table;
  for (const auto& [proto, reader] : GiNaC::get_default_reader())
    if (find_math_function(proto.first) && proto.second == 1) table[proto] = reader;
  add_motion_law_readers(table);
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
  if (item.rfind("outputs.", 0) == 0)
    return "outputs are functions of the coordinates, t and the parameters; an output's rate "
           "is its NAME.v column";
  if (item.rfind("forces[", 0) == 0)
    return "only a force's f and a torque's value may use velocities (xd_<body>, yd_<body>, "
           "phid_<body>, <name>_d); a spring-damper's damping gives its own";
  return "expressions may not use velocities; they follow from the positions";
}

}  // namespace

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
  for (const auto& b : m.bodies) {
    for (const char* prefix : {"x_", "y_", "phi_"}) {
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
  // The names loads use (format 7.2): xd_<body>, yd_<body>, phid_<body>, <coordinate>_d.
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const char* const kRates[] = {"xd_", "yd_", "phid_"};
    for (int c = 0; c < 3; ++c) names_[kRates[c] + m.bodies[b].name] = qd_[3 * b + c];
  }
  for (std::size_t c = 0; c < m.coordinates.size(); ++c)
    names_[m.coordinates[c].name + "_d"] = qd_[3 * m.bodies.size() + c];
  // Parameters in file order, each seeing only the earlier ones: a value that reads another
  // parameter makes a derived one (unless --param overrides it, which drops the formula).
  params_.reserve(m.parameters.size());
  for (std::size_t i = 0; i < m.parameters.size(); ++i) {
    const Parameter& p = m.parameters[i];
    const bool forced = std::find(overridden.begin(), overridden.end(), p.name) != overridden.end();
    if (!forced) {
      const ex value = parse(p.value, Scope::kGeometry, "parameters." + p.name);
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
    names_[d.name] = parse(d.value, Scope::kDriver, "definitions." + d.name);
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
    throw InputError(source_, item, expr.loc,
                     "cannot read '" + expr.text + "': " + clean_message(err.what()));
  }
  for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it) {
    if (GiNaC::is_a<GiNaC::symbol>(*it)) {
      const Input role = classify(*it);
      const std::string name = GiNaC::ex_to<GiNaC::symbol>(*it).get_name();
      if (role.kind == InputKind::kQd && !scope_allows(scope, role.kind))
        throw InputError(
            source_, item, expr.loc,
            "'" + expr.text + "' uses the velocity '" + name + "': " + velocity_hint(item));
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
