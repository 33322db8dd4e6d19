#include "kinegen/codegen/emit_cpp.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace kinegen::codegen {

namespace {

// Precedence of a printed expression, to decide on parentheses.
enum Prec { kSum = 1, kUnary = 2, kProduct = 3, kAtom = 4 };

struct Printed {
  std::string text;
  Prec prec;
};

// Integers that double (and T(int) for float, through double) holds exactly.
bool is_small_integer(const GiNaC::numeric& x) {
  return x.is_integer() && GiNaC::abs(x) <= GiNaC::numeric(1L << 53);
}

std::string str(const GiNaC::numeric& x) {
  std::ostringstream os;
  os << x;
  return os.str();
}

std::string safe_comment_text(const std::string& s) {
  std::string out;
  for (char ch : s)
    out += (std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '.' || ch == '-' ||
            ch == '+')
               ? ch
               : '?';
  return out;
}

class FunctionPrinter {
 public:
  FunctionPrinter(const Program& program, const SymbolTable& symbols)
      : p_(program), symbols_(symbols), names_(program.nodes.size()) {}

  // The body of a generated function: the intermediate terms, then `out[k] = ...;`.
  std::string body(const char* indent) {
    std::ostringstream os;
    int count = 0;
    for (const auto& n : p_.nodes) count += n.named;
    if (count > 0) os << indent << "// Intermediate terms (" << count << ")\n";
    int next = 0;
    for (std::size_t k = 0; k < p_.nodes.size(); ++k) {
      if (!p_.nodes[k].named) continue;
      const std::string name = "_t" + std::to_string(next++);
      os << indent << "const T " << name << " = " << print(static_cast<int>(k)).text << ";\n";
      names_[k] = name;
    }
    if (count > 0 && !p_.outputs.empty()) os << "\n";
    for (std::size_t o = 0; o < p_.outputs.size(); ++o) {
      const int id = p_.outputs[o];
      os << indent << "out[" << o << "] = " << (id == Program::kZero ? "T(0)" : print(id).text)
         << ";\n";
    }
    return os.str();
  }

 private:
  std::string atom(int id) {
    const Printed e = print(id);
    return e.prec == kAtom ? e.text : "(" + e.text + ")";
  }

  Printed constant(const Node& n) {
    if (GiNaC::is_a<GiNaC::numeric>(n.exact)) {
      const auto x = GiNaC::ex_to<GiNaC::numeric>(n.exact);
      if (is_small_integer(x)) return {"T(" + str(x) + ")", kAtom};
      if (x.is_rational() && is_small_integer(x.numer()) && is_small_integer(x.denom()))
        return {"T(" + str(x.numer()) + ")/T(" + str(x.denom()) + ")", kProduct};
    }
    return {"T(" + format_double(n.value) + ")", kAtom};
  }

  Printed input(const Node& n) {
    switch (n.input.kind) {
      case InputKind::kQ: return {"q[" + std::to_string(n.input.index) + "]", kAtom};
      case InputKind::kQd: return {"qd[" + std::to_string(n.input.index) + "]", kAtom};
      case InputKind::kT: return {"t", kAtom};
      case InputKind::kParam: return {"T(p." + symbols_.param_name(n.input.index) + ")", kAtom};
    }
    return {"?", kAtom};
  }

  std::string power(int base, int n) {
    if (n > kMaxUnrolledPower) return "pow(" + print(base).text + ", T(" + std::to_string(n) + "))";
    const std::string b = atom(base);
    std::string s = b;
    for (int k = 1; k < n; ++k) s += "*" + b;
    return s;
  }

  // A sum's term: returns the sign it should be joined with and the text of its magnitude.
  std::pair<bool, Printed> signed_term(int id) {
    const Node& n = p_.nodes[id];
    if (names_[id].empty() && n.kind == OpKind::kMul && !n.args.empty()) {
      const Node& c = p_.nodes[n.args[0]];
      if (c.kind == OpKind::kConst && GiNaC::is_a<GiNaC::numeric>(c.exact) &&
          GiNaC::ex_to<GiNaC::numeric>(c.exact).is_negative()) {
        return {true, product(n, /*negate_coefficient=*/true)};
      }
    }
    return {false, print(id)};
  }

  Printed product(const Node& n, bool negate_coefficient) {
    std::string num, den;
    bool leading_minus = false;
    for (std::size_t a = 0; a < n.args.size(); ++a) {
      const int id = n.args[a];
      const Node& arg = p_.nodes[id];
      if (is_divisor(arg)) {
        const int m = -arg.exponent;
        den += "/" + (m == 1 ? atom(arg.args[0]) : "(" + power(arg.args[0], m) + ")");
        continue;
      }
      std::string factor;
      if (a == 0 && arg.kind == OpKind::kConst && GiNaC::is_a<GiNaC::numeric>(arg.exact)) {
        GiNaC::numeric c = GiNaC::ex_to<GiNaC::numeric>(arg.exact);
        if (negate_coefficient) c = -c;
        if (c == -1 && n.args.size() > 1 && !is_divisor(p_.nodes[n.args[1]])) {
          leading_minus = true;
          continue;
        }
        if (c == 1 && n.args.size() > 1 && !is_divisor(p_.nodes[n.args[1]])) continue;
        Node shown = arg;
        shown.exact = c;
        shown.value = c.to_double();
        const Printed pc = constant(shown);
        factor = pc.prec == kAtom ? pc.text : "(" + pc.text + ")";
      } else {
        factor = atom(id);
      }
      num += (num.empty() ? "" : "*") + factor;
    }
    if (num.empty()) num = "T(1)";
    std::string s = num + den;
    if (leading_minus) return {"-" + s, kUnary};
    return {s, kProduct};
  }

  Printed print(int id) {
    if (!names_[id].empty()) return {names_[id], kAtom};
    const Node& n = p_.nodes[id];
    const auto call = [&](const char* f) { return Printed{std::string(f) + "(" + print(n.args[0]).text + ")", kAtom}; };
    switch (n.kind) {
      case OpKind::kConst: return constant(n);
      case OpKind::kInput: return input(n);
      case OpKind::kAdd: {
        std::string s;
        for (std::size_t a = 0; a < n.args.size(); ++a) {
          auto [negative, term] = signed_term(n.args[a]);
          const std::string text = term.prec <= kSum ? "(" + term.text + ")" : term.text;
          if (a == 0)
            s = negative ? "-" + (term.prec < kProduct ? "(" + term.text + ")" : term.text) : text;
          else
            s += (negative ? " - " : " + ") +
                 (negative && term.prec < kProduct ? "(" + term.text + ")" : text);
        }
        return {s, kSum};
      }
      case OpKind::kMul: return product(n, false);
      case OpKind::kPowInt:
        if (n.exponent > 0) {
          const std::string s = power(n.args[0], n.exponent);
          return {s, n.exponent == 1 || n.exponent > kMaxUnrolledPower ? kAtom : kProduct};
        }
        return {"T(1)/" + (n.exponent == -1 ? atom(n.args[0]) : "(" + power(n.args[0], -n.exponent) + ")"),
                kProduct};
      case OpKind::kPow:
        return {"pow(" + print(n.args[0]).text + ", " + print(n.args[1]).text + ")", kAtom};
      case OpKind::kSqrt: return call("sqrt");
      case OpKind::kSin: return call("sin");
      case OpKind::kCos: return call("cos");
      case OpKind::kTan: return call("tan");
      case OpKind::kAsin: return call("asin");
      case OpKind::kAcos: return call("acos");
      case OpKind::kAtan: return call("atan");
      case OpKind::kExp: return call("exp");
      case OpKind::kLog: return call("log");
    }
    return {"?", kAtom};
  }

  const Program& p_;
  const SymbolTable& symbols_;
  std::vector<std::string> names_;
};

template <class Container>
std::string join(const Container& values) {
  std::string s;
  for (const auto& v : values) s += (s.empty() ? "" : ", ") + v;
  return s;
}

void emit_function(std::ostringstream& os, const char* name, const char* out_size,
                   const Program& program, const SymbolTable& symbols, bool with_qd) {
  os << "  template <class T>\n";
  os << "  static void " << name << "([[maybe_unused]] const T* q,";
  if (with_qd) os << " [[maybe_unused]] const T* qd,";
  os << "\n      [[maybe_unused]] T t, [[maybe_unused]] const Params& p, T* out) noexcept {\n";
  os << "    // out[" << out_size << "]; " << program.operation_count() << " operations\n";
  // Unqualified calls after using-declarations: std's overloads for float, double and
  // std::complex, and argument-dependent lookup for other scalar types.
  static const std::pair<OpKind, const char*> kFunctions[] = {
      {OpKind::kAcos, "acos"}, {OpKind::kAsin, "asin"}, {OpKind::kAtan, "atan"},
      {OpKind::kCos, "cos"},   {OpKind::kExp, "exp"},   {OpKind::kLog, "log"},
      {OpKind::kPow, "pow"},   {OpKind::kSin, "sin"},   {OpKind::kSqrt, "sqrt"},
      {OpKind::kTan, "tan"}};
  std::string used;
  for (const auto& [kind, fname] : kFunctions) {
    bool uses = false;
    for (const auto& n : program.nodes)
      uses = uses || n.kind == kind ||
             (kind == OpKind::kPow && n.kind == OpKind::kPowInt &&
              std::abs(n.exponent) > kMaxUnrolledPower);
    if (uses) used += std::string(used.empty() ? "" : ", ") + "std::" + fname;
  }
  if (!used.empty()) os << "    using " << used << ";\n";
  os << FunctionPrinter(program, symbols).body("    ");
  os << "  }\n";
}

}  // namespace

std::string format_double(double value) {
  if (value == 0) return "0";
  // The shortest form that reads back to the same double.
  char buf[40];
  for (int digits = 15; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, value);
    if (std::strtod(buf, nullptr) == value) break;
  }
  std::string s = buf;
  // Keep it a floating literal so T(...) never sees an integer that overflows int.
  if (s.find_first_of(".en") == std::string::npos) s += ".0";
  return s;
}

std::string emit_header(const Mechanism& m, const SymbolTable& symbols, const SymbolicModel& model,
                        const ModelPrograms& programs) {
  std::string base = m.source;
  if (const auto slash = base.find_last_of("/\\"); slash != std::string::npos)
    base = base.substr(slash + 1);
  base = safe_comment_text(base);

  std::ostringstream os;
  os << "// Generated by kinegen " << kVersion << " from " << base << ". Do not edit.\n"
     << "// Regenerate with: kinegen generate " << base << " -o <dir>\n"
     << "//\n"
     << "// Planar Cartesian kinematics of mechanism '" << m.name << "': Phi(q, t) = 0 with\n"
     << "// nu = -Phi_t and gamma = -(Phi_q qd)_q qd - 2 Phi_qt qd - Phi_tt.\n"
     << "#pragma once\n\n#include <array>\n#include <cmath>\n\n"
     << "namespace kinegen::models {\n\n";

  os << "// Coordinates:";
  for (int k = 0; k < programs.nq; ++k)
    os << (k % 3 == 0 ? "\n//  " : ",") << " q[" << k << "] = " << symbols.coord_name(k);
  os << "\n// Constraint rows:\n";
  for (int r = 0; r < programs.nc; ++r) {
    const Constraint* c = model.rows[r].constraint;
    if (model.rows[r].component > 0) continue;
    const int n = c->equation_count();
    // c->item is built from validated names and the constraint type only.
    os << "//   " << (n == 1 ? std::to_string(r) : std::to_string(r) + "-" + std::to_string(r + n - 1))
       << ": " << c->item << "\n";
  }
  os << "struct " << m.name << " {\n";
  os << "  static constexpr int nq = " << programs.nq << ";\n";
  os << "  static constexpr int nc = " << programs.nc << ";\n";
  os << "  static constexpr int jac_nnz = " << programs.jac_rows.size() << ";\n";
  std::vector<std::string> rows, cols, q0;
  for (int r : programs.jac_rows) rows.push_back(std::to_string(r));
  for (int c : programs.jac_cols) cols.push_back(std::to_string(c));
  for (const auto& e : model.q0)
    q0.push_back(format_double(to_double(substitute_params(e, symbols, model.param_values))));
  os << "  static constexpr std::array<int, jac_nnz> jac_rows = {" << join(rows) << "};\n";
  os << "  static constexpr std::array<int, jac_nnz> jac_cols = {" << join(cols) << "};\n";
  os << "  // Initial estimates for the first position solve, from the mechanism file.\n";
  os << "  static constexpr std::array<double, nq> q0 = {" << join(q0) << "};\n";
  os << "  // A typical length of the mechanism; position tolerances scale with it.\n";
  os << "  static constexpr double length_scale = " << format_double(model.length_scale) << ";\n\n";
  os << "  struct Params {\n";
  for (int k = 0; k < symbols.num_params(); ++k)
    os << "    double " << symbols.param_name(k) << " = "
       << format_double(model.param_values[k].to_double()) << ";\n";
  os << "  };\n\n";

  os << "  // Phi(q, t)\n";
  emit_function(os, "phi", "nc", programs.phi, symbols, false);
  os << "\n  // Phi_q(q, t) at (jac_rows[k], jac_cols[k])\n";
  emit_function(os, "phi_q", "jac_nnz", programs.phi_q, symbols, false);
  os << "\n  // nu = -Phi_t\n";
  emit_function(os, "nu", "nc", programs.nu, symbols, false);
  os << "\n  // gamma = -(Phi_q qd)_q qd - 2 Phi_qt qd - Phi_tt\n";
  emit_function(os, "gamma", "nc", programs.gamma, symbols, true);
  os << "};\n\n}  // namespace kinegen::models\n";
  return os.str();
}

}  // namespace kinegen::codegen
