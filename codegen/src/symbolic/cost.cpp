// Bounded cost: GiNaC evaluates exact numbers eagerly (2^(2^40) is computed while the text
// is read, until GMP gives up and aborts the process), and derivatives of long products grow
// with the square of their length. Both are bounded here before the work is done.

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
#include "kinegen/kernels/motion_law.hpp"
#include "symbolic_detail.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

using namespace symbolic_detail;

namespace {

// Exponents beyond this are refused (no mechanism needs x^1000).
constexpr long double kMaxExponent = 1000;
// An exact power of a number may have at most this many decimal digits.
constexpr long double kMaxPowerDigits = 10000;
// A literal's decimal exponent (1e4000): larger literals would be exact numbers of that many
// digits.
constexpr long kMaxLiteralExponent = 4000;

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

namespace symbolic_detail {

std::string short_value(long double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6Lg", v);
  return buf;
}

void check_text_cost(const std::string& text) { CostScanner(text).run(); }

// Exact powers that the parameters' values would make too costly (see check_power).
void check_cost(const Mechanism& m, const SymbolTable& s, const std::vector<GiNaC::numeric>& values,
                const ex& value, const Expr& e, const std::string& item) {
  try {
    approximate(value, s, values);
  } catch (const CostError& err) {
    throw InputError(m.source, item, e.loc, err.what());
  }
}

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
    // A driver's pieces: select(c, lo', hi'), each piece differentiated alone.
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

// Where row `component` of a constraint is written: its equation, a driver's f, or the item.
SourceLoc row_loc(const Constraint& c, int component) {
  if (!c.equations.empty()) return c.equations[component].loc;
  return c.is_driver ? c.value.loc : c.loc;
}

}  // namespace symbolic_detail

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

}  // namespace kinegen::codegen
