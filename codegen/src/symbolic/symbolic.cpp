#include "kinegen/codegen/symbolic/symbolic.hpp"

#include <cln/cln.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/symbolic/forces.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

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

// --- Bounded cost. GiNaC evaluates exact numbers eagerly (2^(2^40) is computed while the text
// is read, until GMP gives up and aborts the process), and derivatives of long products grow
// with the square of their length. Both are bounded before the work is done.

// Exponents beyond this are refused (no mechanism needs x^1000).
constexpr long double kMaxExponent = 1000;
// An exact power of a number may have at most this many decimal digits.
constexpr long double kMaxPowerDigits = 10000;
// A literal's decimal exponent (1e4000): larger literals would be exact numbers of that many
// digits.
constexpr long kMaxLiteralExponent = 4000;
// The estimated size of one derivative, and of all of a model's together (a 1000-body chain's
// are about N; hostile products of 300 factors reach 1e7 and more).
constexpr double kMaxDerivativeSize = 2e5;
constexpr double kMaxDerivedSize = 5e7;
// Terms of an expanded equation (check_expansion_cost).
constexpr double kMaxExpandedTerms = 1e5;

// The cost of exact arithmetic exceeds a limit; the message says which.
struct CostError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string short_value(long double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6Lg", v);
  return buf;
}

// A value known approximately while the exact one is not computed yet: `known` is false when it
// depends on a coordinate or t (then no exact number can grow from it).
struct Approx {
  long double v = 0;
  bool known = true;
};

Approx combine(Approx a, Approx b, long double v) { return {v, a.known && b.known}; }

// Refuses a power whose exact value or exponent would be too large. `text` names it.
void check_power(Approx base, Approx exponent, const std::string& text) {
  if (!exponent.known) return;
  if (!(fabsl(exponent.v) <= kMaxExponent))
    throw CostError("the exponent " + (std::isfinite(exponent.v) ? short_value(exponent.v) : "") +
                    (std::isfinite(exponent.v) ? " " : "") + "in '" + text +
                    "' is beyond the limit of " + short_value(kMaxExponent));
  if (!base.known) return;
  const long double magnitude = fabsl(base.v);
  if (magnitude == 0 || magnitude == 1 || exponent.v == 0) return;
  const long double digits = fabsl(exponent.v) * fabsl(log10l(magnitude));
  if (!(digits <= kMaxPowerDigits))
    throw CostError("'" + text + "' would be an exact number of " +
                    (std::isfinite(digits) ? "about " + short_value(digits) : "too many") +
                    " digits (the limit is " + short_value(kMaxPowerDigits) + ")");
}

long double apply_function(const std::string& name, long double x) {
  if (name == "sin") return sinl(x);
  if (name == "cos") return cosl(x);
  if (name == "tan") return tanl(x);
  if (name == "asin") return asinl(x);
  if (name == "acos") return acosl(x);
  if (name == "atan") return atanl(x);
  if (name == "exp") return expl(x);
  if (name == "log") return logl(x);
  if (name == "sqrt") return sqrtl(x);
  if (const int law = find_motion_law(name); law >= 0) return kernels::motion_law(law, 0, x);
  return NAN;
}

// Reads the text the way GiNaC's parser will, but in long double, before GiNaC does: finds
// every power's operands and refuses those too costly, and chained powers (a^b^c), which
// GiNaC cannot read. Text it does not understand is left to GiNaC's own error messages.
class CostScanner {
 public:
  explicit CostScanner(const std::string& text) : text_(text) {}
  void run() {
    try {
      expr();
    } catch (const Unreadable&) {
    }
  }

 private:
  struct Unreadable {};

  void skip() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
  }
  bool take(char c) {
    skip();
    if (pos_ < text_.size() && text_[pos_] == c) return ++pos_, true;
    return false;
  }
  Approx expr() {
    Approx a = term();
    for (;;) {
      if (take('+')) {
        const Approx b = term();
        a = combine(a, b, a.v + b.v);
      } else if (take('-')) {
        const Approx b = term();
        a = combine(a, b, a.v - b.v);
      } else {
        return a;
      }
    }
  }
  Approx term() {
    Approx a = unary();
    for (;;) {
      if (take('*')) {
        const Approx b = unary();
        a = combine(a, b, a.v * b.v);
      } else if (take('/')) {
        const Approx b = unary();
        a = combine(a, b, a.v / b.v);
      } else {
        return a;
      }
    }
  }
  Approx unary() {
    if (take('-')) {
      Approx a = unary();
      a.v = -a.v;
      return a;
    }
    if (take('+')) return unary();
    return power();
  }
  Approx power() {
    skip();
    const std::size_t from = pos_;
    const Approx base = primary();
    if (!take('^')) return base;
    const Approx exponent = unary_primary();
    const std::string text = text_.substr(from, pos_ - from);
    if (take('^'))
      throw CostError("'" + text +
                      "^...' chains '^', which is ambiguous: write (a^b)^c or a^(b^c)");
    check_power(base, exponent, text);
    return combine(base, exponent, powl(base.v, exponent.v));
  }
  // A power's exponent: a primary, possibly negated (2^-3).
  Approx unary_primary() {
    if (take('-')) {
      Approx a = unary_primary();
      a.v = -a.v;
      return a;
    }
    if (take('+')) return unary_primary();
    return primary();
  }
  Approx primary() {
    skip();
    if (pos_ >= text_.size()) throw Unreadable{};
    const char ch = text_[pos_];
    if (ch == '(') {
      ++pos_;
      const Approx a = expr();
      if (!take(')')) throw Unreadable{};
      return a;
    }
    if (std::isdigit(static_cast<unsigned char>(ch)) || ch == '.') return number();
    if (std::isalpha(static_cast<unsigned char>(ch)) || ch == '_') {
      std::size_t end = pos_;
      while (end < text_.size() &&
             (std::isalnum(static_cast<unsigned char>(text_[end])) || text_[end] == '_'))
        ++end;
      const std::string name = text_.substr(pos_, end - pos_);
      pos_ = end;
      if (take('(')) {
        // GiNaC's reader takes a call without arguments for a call of any arity of that name
        // and crashes on it (sin() read out of bounds), so it never gets one.
        if (take(')'))
          throw CostError("cannot read '" + text_ + "': no function \"" + name +
                          "\" with 0 arguments");
        const Approx a = expr();
        if (!take(')')) throw Unreadable{};
        return {apply_function(name, a.v), a.known};
      }
      if (name == "pi") return {3.14159265358979323846264338327950288L, true};
      return {0, false};
    }
    throw Unreadable{};
  }
  Approx number() {
    const std::size_t from = pos_;
    while (pos_ < text_.size() && std::isdigit(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    if (pos_ < text_.size() && text_[pos_] == '.') ++pos_;
    while (pos_ < text_.size() && std::isdigit(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    if (pos_ < text_.size() && (text_[pos_] == 'e' || text_[pos_] == 'E')) {
      std::size_t p = pos_ + 1;
      if (p < text_.size() && (text_[p] == '+' || text_[p] == '-')) ++p;
      const std::size_t digits_from = p;
      while (p < text_.size() && std::isdigit(static_cast<unsigned char>(text_[p]))) ++p;
      if (p > digits_from) {
        const std::string e = text_.substr(digits_from, p - digits_from);
        if (e.size() > 6 || std::stol(e) > kMaxLiteralExponent)
          throw CostError("the number '" + text_.substr(from, p - from) +
                          "' is beyond the limit of exact numbers (decimal exponents up to " +
                          std::to_string(kMaxLiteralExponent) + ")");
        pos_ = p;
      }
    }
    return {std::strtold(text_.substr(from, pos_ - from).c_str(), nullptr), true};
  }

  const std::string& text_;
  std::size_t pos_ = 0;
};

// The same bounds on a parsed expression once the parameters' values are known (x^n with n a
// parameter of 2^40), before they are substituted.
Approx approximate(const ex& e, const SymbolTable& s, const std::vector<GiNaC::numeric>& values) {
  if (GiNaC::is_a<GiNaC::numeric>(e)) return {GiNaC::ex_to<GiNaC::numeric>(e).to_double(), true};
  if (GiNaC::is_a<GiNaC::constant>(e))  // only pi passes the parser
    return e.is_equal(GiNaC::Pi) ? Approx{3.14159265358979323846264338327950288L, true}
                                 : Approx{0, false};
  if (GiNaC::is_a<GiNaC::symbol>(e)) {
    const Input in = s.classify(e);
    if (in.kind == InputKind::kParam) return {values[in.index].to_double(), true};
    return {0, false};
  }
  if (GiNaC::is_a<GiNaC::power>(e)) {
    const Approx base = approximate(e.op(0), s, values);
    const Approx exponent = approximate(e.op(1), s, values);
    std::ostringstream text;
    text << e;
    check_power(base, exponent, text.str());
    return combine(base, exponent, powl(base.v, exponent.v));
  }
  if (GiNaC::is_a<GiNaC::add>(e) || GiNaC::is_a<GiNaC::mul>(e)) {
    const bool sum = GiNaC::is_a<GiNaC::add>(e);
    Approx a{sum ? 0.0L : 1.0L, true};
    for (std::size_t k = 0; k < e.nops(); ++k) {
      const Approx b = approximate(e.op(k), s, values);
      a = combine(a, b, sum ? a.v + b.v : a.v * b.v);
    }
    return a;
  }
  if (int law = 0, order = 0; is_motion_law(e, law, order)) {
    const Approx a = approximate(e.op(2), s, values);
    return {kernels::motion_law(law, order, a.v), a.known};
  }
  if (GiNaC::is_a<GiNaC::function>(e) && e.nops() == 1) {
    const Approx a = approximate(e.op(0), s, values);
    return {apply_function(GiNaC::ex_to<GiNaC::function>(e).get_name(), a.v), a.known};
  }
  Approx a;
  for (std::size_t k = 0; k < e.nops(); ++k) a = combine(a, approximate(e.op(k), s, values), NAN);
  return a;
}

// Derivatives: the size (leaves and operators of the expression tree) that d e / d x would have,
// estimated from e without building it, so a derivative too large to be worth computing is
// refused before it takes minutes and gigabytes. The product rule makes d(f1 ... fn) about n
// times the size of the product, and every function's derivative repeats its argument.
struct TreeSize {
  double size = 0, derivative = 0;
  bool depends = false;
};

TreeSize tree_size(const ex& e, const ex& x) {
  if (GiNaC::is_a<GiNaC::symbol>(e)) return {1, 1, e.is_equal(x)};
  if (e.nops() == 0) return {1, 0, false};
  std::vector<TreeSize> ops;
  TreeSize r{1, 0, false};
  for (std::size_t k = 0; k < e.nops(); ++k) {
    ops.push_back(tree_size(e.op(k), x));
    r.size += ops.back().size;
    r.depends = r.depends || ops.back().depends;
  }
  if (!r.depends) return r;
  if (is_select(e)) {
    // A driver's pieces (format 6.3): select(c, lo', hi'), each piece differentiated alone.
    r.derivative = 1 + ops[0].size + ops[1].derivative + ops[2].derivative;
  } else if (is_floor(e)) {
    r.derivative = 1;  // whole periods: 0
  } else if (GiNaC::is_a<GiNaC::add>(e)) {
    for (const auto& o : ops) r.derivative += o.derivative;
  } else if (GiNaC::is_a<GiNaC::mul>(e)) {
    for (const auto& o : ops)
      if (o.depends) r.derivative += o.derivative + (r.size - o.size);
  } else {
    // powers and functions: f'(u) repeats u (and f) a few times, times u'
    r.derivative = 3 * r.size + ops.size() * 2;
    for (const auto& o : ops) r.derivative += o.derivative;
  }
  return r;
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
    CostScanner(text).run();
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

// Exact powers that the parameters' values would make too costly (see check_power).
void check_cost(const Mechanism& m, const SymbolTable& s,
                const std::vector<GiNaC::numeric>& values, const ex& value, const Expr& e,
                const std::string& item) {
  try {
    approximate(value, s, values);
  } catch (const CostError& err) {
    throw InputError(m.source, item, e.loc, err.what());
  }
}

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
      throw InputError(m.source, "parameters." + p.name, p.loc,
                       "'" + p.value.text + "' is not a finite real number with the parameters' values");
  }
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
namespace {
void check_defined_value(const Mechanism& m, const SymbolTable& s,
                         const std::vector<GiNaC::numeric>& values, const ex& value, const Expr& e,
                         const std::string& item);
}  // namespace

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
  if (to_double(substitute_params(GiNaC::pow(v.first, 2) + GiNaC::pow(v.second, 2), s_, values_)) ==
      0.0)
    throw InputError(m_.source, c_.item, c_.vector("vi").x.loc, "vi must not be the zero vector");
  const Vec av = rotate(frame_i().phi, v);
  return -av.second * d.first + av.first * d.second;
}

namespace {

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

// A driver's law in pieces, with a period, from a table or a run-time input (format 6.3), as
// one expression in t. Checks the pieces' order, the period and, at every boundary and seam,
// f, f' and f'' from either side: a jump in f throws, one in f' or f'' is added to
// `warnings` when given.
class DriverLawBuilder {
 public:
  DriverLawBuilder(const Constraint& c, const Mechanism& m, const SymbolTable& s,
                   const std::vector<GiNaC::numeric>& values)
      : c_(c), m_(m), s_(s), values_(values) {}

  ex build(std::vector<std::string>* warnings) const {
    const DriverLaw& law = c_.law;
    const ex t = s_.t();
    std::optional<ex> period;
    if (law.period) {
      period = geometry_value(m_, s_, values_, *law.period, c_.item + " period");
      if (!(number(*period) > 0))
        fail(law.period->loc,
             "period must be greater than 0 (it is " + format_number(number(*period)) + ")");
    }
    if (law.table_id >= 0) {
      const Spline& spline = registered_table(law.table_id);
      if (period && std::abs(number(*period) - spline.period) >
                        1e-12 * std::max(1.0, std::abs(spline.period)))
        fail(law.period->loc, "a periodic table's period must be its last t (" +
                                  format_number(spline.period) + "), not " +
                                  format_number(number(*period)));
      return kinegen_table(law.table_id, 0, t);
    }
    if (law.input) return kinegen_input_law(t);
    // Pieces: f_k on [until_{k-1}, until_k), the last one open.
    const std::size_t n = law.pieces.size();
    std::vector<ex> f(n), until(n - 1);
    std::vector<double> at(n - 1);
    for (std::size_t k = 0; k < n; ++k) {
      const DriverPiece& p = law.pieces[k];
      const std::string item = piece_item(k);
      f[k] = s_.parse(p.f, Scope::kDriverTime, item + " f");
      check_defined_value(m_, s_, values_, f[k], p.f, item + " f");
      if (k + 1 == n) break;
      until[k] = geometry_value(m_, s_, values_, p.until, item + " until");
      at[k] = number(until[k]);
      if (k > 0 && !(at[k] > at[k - 1]))
        fail(p.until.loc, "pieces out of order: until " + format_number(at[k]) +
                              " must be greater than the previous piece's " +
                              format_number(at[k - 1]));
      if (period && !(at[k] > 0 && at[k] < number(*period)))
        fail(p.until.loc, "until " + format_number(at[k]) + " must lie inside (0, period) = (0, " +
                              format_number(number(*period)) + ")");
    }
    // The law in x: t itself, or t wrapped into [0, T).
    const ex x = period ? t - *period * kinegen_floor(t / *period) : t;
    ex value = f[n - 1].subs(t == x);
    for (std::size_t k = n - 1; k-- > 0;)
      value = kinegen_select(x - until[k], f[k].subs(t == x), value);
    std::vector<Joint> joints;
    for (std::size_t k = 0; k + 1 < n; ++k)
      joints.push_back({f[k], f[k + 1], until[k], until[k],
                        "the boundary t = " + format_number(at[k]), law.pieces[k + 1].loc});
    if (period) {
      // Each period adds f(T) - f(0); the seam compares the last piece's end with the first
      // piece's start moved up by that rise.
      const ex rise = f[n - 1].subs(t == *period) - f[0].subs(t == 0);
      value += kinegen_floor(t / *period) * rise;
      joints.push_back({f[n - 1], f[0] + rise, *period, 0,
                        "the period's seam t = " + format_number(number(*period)),
                        law.period->loc});
    }
    // Where the law's magnitudes are sampled (the scale of its jumps): inside each piece.
    std::vector<std::pair<ex, ex>> spans;  // a piece and a time inside it
    {
      const double first = n > 1 ? at[0] : 0, last = n > 1 ? at[n - 2] : 0;
      const double length = period  ? number(*period) / n
                            : n > 2 ? (last - first) / (n - 2)
                                    : std::max(1.0, std::abs(first));
      for (std::size_t k = 0; k < n; ++k) {
        const double lo = k == 0 ? (period ? 0.0 : first - length) : at[k - 1];
        const double hi = k + 1 < n ? at[k] : (period ? number(*period) : last + length);
        for (int i = 1; i <= 3; ++i)
          spans.emplace_back(f[k], GiNaC::numeric(exact_double(lo + (hi - lo) * i / 4)));
      }
    }
    check_joints(joints, spans, warnings);
    return value;
  }

 private:
  struct Joint {
    ex before, after;        // the pieces on either side (in t)
    ex at_before, at_after;  // where each is taken
    std::string name;
    SourceLoc loc;  // the piece after it
  };

  // f, f', f'' across each joint; a difference above 1e-9 of the law's largest magnitude of
  // that derivative (over the joints and `samples`, times inside each piece) counts. At 40
  // digits, so rounding never does.
  // An exact rational of a double, for a sampling time.
  static GiNaC::numeric exact_double(double v) {
    return GiNaC::numeric(cln::rational(cln::the<cln::cl_R>(GiNaC::numeric(v).to_cl_N())));
  }

  void check_joints(const std::vector<Joint>& joints, const std::vector<std::pair<ex, ex>>& samples,
                    std::vector<std::string>* warnings) const {
    if (joints.empty()) return;
    const ex t = s_.t();
    const DigitsGuard digits(kEvalDigits);
    double left[3][kMaxJoints], right[3][kMaxJoints];
    const std::size_t count = std::min(joints.size(), kMaxJoints);
    double scale[3] = {0, 0, 0};
    // Each side is taken a hair inside its piece (1e-25 of the time's size, far below the
    // 1e-9 that counts), so that a clamped law's corner at the boundary (harmonic'' at 0)
    // is seen as its piece's one-sided limit, not as the clamped value.
    const GiNaC::numeric hair = GiNaC::numeric(1, 10).power(25);
    for (std::size_t j = 0; j < count; ++j) {
      ex a = joints[j].before, b = joints[j].after;
      const ex tb = joints[j].at_before, ta = joints[j].at_after;
      const ex before = tb - hair * std::max(1.0, std::abs(number(tb)));
      const ex after = ta + hair * std::max(1.0, std::abs(number(ta)));
      for (int o = 0; o < 3; ++o) {
        left[o][j] = number(a.subs(t == before));
        right[o][j] = number(b.subs(t == after));
        scale[o] = std::max({scale[o], std::abs(left[o][j]), std::abs(right[o][j])});
        a = a.diff(GiNaC::ex_to<GiNaC::symbol>(t));
        b = b.diff(GiNaC::ex_to<GiNaC::symbol>(t));
      }
    }
    for (const auto& [piece, at] : samples) {
      ex e = piece;
      for (int o = 0; o < 3; ++o) {
        const double v = std::abs(number(e.subs(t == at)));
        if (std::isfinite(v)) scale[o] = std::max(scale[o], v);
        e = e.diff(GiNaC::ex_to<GiNaC::symbol>(t));
      }
    }
    const char* what[3] = {"f", "f'", "f''"};
    for (std::size_t j = 0; j < count; ++j)
      for (int o = 0; o < 3; ++o) {
        if (!(std::abs(left[o][j] - right[o][j]) > 1e-9 * scale[o]) &&
            std::isfinite(left[o][j] - right[o][j]))
          continue;
        const std::string message = std::string(what[o]) + " jumps at " + joints[j].name + ": " +
                                    format_number(left[o][j]) + " before it, " +
                                    format_number(right[o][j]) + " after it";
        if (o == 0) fail(joints[j].loc, message);
        if (warnings)
          warnings->push_back(m_.source + ":" + std::to_string(joints[j].loc.line) + ": " +
                              c_.item + ": " + message +
                              (o == 1 ? "; velocities jump there" : "; accelerations jump there"));
      }
  }

  // The run-time input law: inputs(driver, order, t) (functions.hpp), its derivatives the
  // inputs of the next order.
  ex kinegen_input_law(const ex& t) const { return kinegen_input(driver_index(), 0, t); }

  int driver_index() const {
    for (std::size_t k = 0; k < m_.drivers.size(); ++k)
      if (&m_.drivers[k] == &c_) return static_cast<int>(k);
    throw std::logic_error("an input driver that is not in the mechanism");
  }

  std::string piece_item(std::size_t k) const { return c_.item + " f[" + std::to_string(k) + "]"; }

  double number(const ex& e) const { return to_double(substitute_params(e, s_, values_)); }

  [[noreturn]] void fail(const SourceLoc& loc, const std::string& message) const {
    throw InputError(m_.source, c_.item, loc, message);
  }

  static constexpr std::size_t kMaxJoints = 1001;
  const Constraint& c_;
  const Mechanism& m_;
  const SymbolTable& s_;
  const std::vector<GiNaC::numeric>& values_;
};

}  // namespace

std::vector<std::string> driver_law_warnings(const Mechanism& m, const SymbolTable& s,
                                             const std::vector<GiNaC::numeric>& values) {
  std::vector<std::string> warnings;
  for (const Constraint& c : m.drivers)
    if (!c.law.pieces.empty()) DriverLawBuilder(c, m, s, values).build(&warnings);
  return warnings;
}

ex EquationContext::value() const {
  if (c_.is_driver && !c_.law.plain()) return DriverLawBuilder(c_, m_, s_, values_).build(nullptr);
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

namespace {

// Where row `component` of a constraint is written: its equation, a driver's f, or the item.
SourceLoc row_loc(const Constraint& c, int component) {
  if (!c.equations.empty()) return c.equations[component].loc;
  return c.is_driver ? c.value.loc : c.loc;
}

// The number of terms e.expand() would have, estimated without expanding: sums add, products
// multiply, and (t1 + ... + tn)^k has C(n + k - 1, k) terms.
double expanded_terms(const ex& e) {
  if (GiNaC::is_a<GiNaC::add>(e)) {
    double n = 0;
    for (std::size_t k = 0; k < e.nops(); ++k) n += expanded_terms(e.op(k));
    return n;
  }
  if (GiNaC::is_a<GiNaC::mul>(e)) {
    double n = 1;
    for (std::size_t k = 0; k < e.nops(); ++k) n *= expanded_terms(e.op(k));
    return n;
  }
  if (GiNaC::is_a<GiNaC::power>(e) && GiNaC::is_a<GiNaC::numeric>(e.op(1))) {
    const GiNaC::numeric& k = GiNaC::ex_to<GiNaC::numeric>(e.op(1));
    if (!k.is_pos_integer()) return 1;
    const double n = expanded_terms(e.op(0)), kd = k.to_double();
    if (n <= 1) return 1;
    return std::exp(std::lgamma(n + kd) - std::lgamma(kd + 1) - std::lgamma(n));
  }
  return 1;
}

}  // namespace

void check_expansion_cost(const Mechanism& m, const SymbolicModel& model) {
  for (std::size_t r = 0; r < model.phi.size(); ++r) {
    const double terms = expanded_terms(model.phi[r]);
    if (terms <= kMaxExpandedTerms) continue;
    const Constraint& c = *model.rows[r].constraint;
    const SourceLoc loc = row_loc(c, model.rows[r].component);
    throw InputError(m.source, c.item, loc,
                     "expanded (to find the linear equations), this equation would have about " +
                         short_value(terms) + " terms, beyond the limit of " +
                         short_value(kMaxExpandedTerms) +
                         "; write it without high powers of long sums");
  }
}

namespace {
// The quantity each free coordinate measures (format 7.1): its row of Phi with the input at
// 0, g(q) - z for the angle and position types, |d|^2 - z^2 for distance; and its rate.
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

SymbolicModel derive(const Mechanism& m, const SymbolTable& s,
                     const std::vector<ParamOverride>& overrides) {
  SymbolicModel model;
  model.param_values = parameter_values(m, s, overrides);
  model.warnings = driver_law_warnings(m, s, model.param_values);
  const Builder builder(m, s, model.param_values);

  for (const auto* c : m.constraints()) {
    const auto rows = builder.equations(*c);
    for (std::size_t k = 0; k < rows.size(); ++k) {
      model.phi.push_back(rows[k]);
      model.rows.push_back({c, static_cast<int>(k)});
    }
  }
  const int nc = static_cast<int>(model.phi.size());
  derive_free_values(m, s, model);

  // Every derivative's size is estimated before it is computed (tree_size); one too large, or
  // a model whose derivatives together are, is refused with the constraint it comes from.
  double derived = 0;
  const auto diff = [&](const ex& e, const GiNaC::symbol& x, int r) {
    const double size = tree_size(e, x).derivative;
    derived += size;
    if (size > kMaxDerivativeSize || derived > kMaxDerivedSize) {
      const Constraint& c = *model.rows[r].constraint;
      const SourceLoc loc = row_loc(c, model.rows[r].component);
      throw InputError(
          m.source, c.item, loc,
          "its derivatives would grow to about " + short_value(size) + " nodes" +
              (size > kMaxDerivativeSize
                   ? ""
                   : " (with the earlier rows' " + short_value(derived) + ")") +
              ", beyond the limit of " +
              short_value(size > kMaxDerivativeSize ? kMaxDerivativeSize : kMaxDerivedSize) +
              "; write the expression more compactly");
    }
    return e.diff(x);
  };

  // Each row is differentiated only by the coordinates it reads (a joint reads at most two
  // bodies): derivation stays linear in the size of the mechanism. Derivatives read no
  // coordinate their expression does not, so w = Phi_q qd below needs no others either.
  std::vector<std::vector<int>> row_coords(nc);
  std::vector<std::size_t> row_begin(nc + 1, 0);  // row r's entries: [row_begin[r], row_begin[r+1])
  for (int r = 0; r < nc; ++r) {
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

  for (const auto& b : m.bodies) {
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
  for (const auto& o : m.outputs) {
    const ex value = s.parse(o.value, Scope::kDriver, "outputs." + o.name);
    const std::vector<int> coords = coordinates_in(value, s);
    std::vector<ex> grad(s.nq(), ex(0));
    ex rate = value.diff(s.t());
    for (int k : coords) {
      grad[k] = value.diff(s.q(k));
      rate += grad[k] * s.qd(k);
    }
    // The rate reads only the coordinates the value does, and qd.
    ex a0 = rate.diff(s.t());
    for (int k : coords) a0 += rate.diff(s.q(k)) * s.qd(k);
    model.output_values.push_back(value);
    model.output_rates.push_back(rate);
    model.output_a0.push_back(a0);
    model.output_q.insert(model.output_q.end(), grad.begin(), grad.end());
  }

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
    for (const auto& [body, v] : offsets(*c)) {
      const auto lv = builder.vec(*v, c->item);
      grow(body, lv.first);
      grow(body, lv.second);
    }
    if (c->kind->squared_distance && !c->is_driver) {
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
    if (c->i != kGround && c->j != kGround) {
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
  for (const auto& c : m.coordinates) {
    model.coordinate_kinds.push_back(c.kind);
    model.coordinate_scales.push_back(scale_of(c.kind, model.length_scale));
  }
  return model;
}

}  // namespace kinegen::codegen
