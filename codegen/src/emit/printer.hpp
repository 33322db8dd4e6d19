// The emit stage's printer: one lowered program as C++ statements (FunctionPrinter), and the
// plain functions of a header (phi, phi_q, nu, gamma, outputs) printed whole, in parts
// (split_program) or as repeated pieces (roll_outputs). Private to the emit stage: the block
// solver (block_solver.hpp) and the header layout (emit_cpp.cpp) print through it.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/emit/embedded_kernels.hpp"
#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "kinegen/codegen/emit/reserved_names.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/program/partition.hpp"
#include "kinegen/codegen/program/repeated.hpp"
#include "kinegen/codegen/structure/block_program.hpp"
#include "kinegen/codegen/structure/structure.hpp"

namespace kinegen::codegen::emit_detail {

// Precedence of a printed expression, to decide on parentheses.
enum Prec { kSum = 1, kUnary = 2, kProduct = 3, kAtom = 4 };

struct Printed {
  std::string text;
  Prec prec;
};

// Integers that double (and T(int) for float, through double) holds exactly.
bool is_small_integer(const GiNaC::numeric& x);

std::string str(const GiNaC::numeric& x);

std::string safe_comment_text(const std::string& s);

// The Params members of input driver k (`f: input`): its value, rate and acceleration,
// NAME, NAME_v and NAME_a.
std::string input_member(const Mechanism& m, int driver, int order);

// The members FunctionPrinter wrote as `p.@inK.O@`, named.
std::string with_input_members(std::string header, const Mechanism& m);

// A table's function as FunctionPrinter writes it, `_tbl@ID@` (ID its registry number), until
// with_expression_kernels numbers the tables of the header from 0.
std::string table_token(int id);

class FunctionPrinter {
 public:
  FunctionPrinter(const Program& program, const SymbolTable& symbols)
      : p_(program), symbols_(symbols), names_(program.nodes.size()) {}

  // The body of a generated function: the intermediate terms, then `out[k] = ...;`.
  // first_output: the index of the program's first output in `out` (a part of a split function).
  // out_index: where output k goes, out_index[first_output + k] (outputs taken from a larger
  // set); or, with outputs_through_table, out[_o[k]] (a repeated constraint's function).
  std::string body(const char* indent, int first_output = 0,
                   const std::vector<int>* out_index = nullptr,
                   bool outputs_through_table = false) {
    std::ostringstream os;
    int count = 0;  // the named terms not bound to the caller's variables
    for (std::size_t k = 0; k < p_.nodes.size(); ++k)
      count += p_.nodes[k].named && !named(static_cast<int>(k));
    if (count > 0) os << indent << "// Intermediate terms (" << count << ")\n";
    int next = 0;
    for (std::size_t k = 0; k < p_.nodes.size(); ++k) {
      if (!p_.nodes[k].named || named(static_cast<int>(k))) continue;
      const std::string name = "_t" + std::to_string(next++);
      os << indent << "const T " << name << " = " << print(static_cast<int>(k)).text << ";\n";
      names_[k] = name;
    }
    // As SymForce does: the terms, then the outputs, each section headed with its size.
    if (count > 0 && !p_.outputs.empty())
      os << "\n" << indent << "// Output terms (" << p_.outputs.size() << ")\n";
    for (std::size_t o = 0; o < p_.outputs.size(); ++o) {
      const int id = p_.outputs[o];
      const int k = first_output + static_cast<int>(o);
      const std::string target = outputs_through_table ? "_o[" + std::to_string(o) + "]"
                                 : out_index           ? std::to_string((*out_index)[k])
                                                       : std::to_string(k);
      os << indent << "out[" << target << "] = " << (id == Program::kZero ? "T(0)" : print(id).text)
         << ";\n";
    }
    return os.str();
  }

  // Demand-driven printing, for functions whose outputs are interleaved with solves: prints
  // (as `const T _tK = ...;`) the named terms `id` needs that are not yet in scope, skipping
  // those `allowed` rejects (they are printed later, nearer their use).
  void ensure(int id, std::ostream& os, const std::string& indent,
              const std::function<bool(int)>& allowed = nullptr) {
    if (id == Program::kZero || !names_[id].empty()) return;
    const Node& n = p_.nodes[id];
    for (int a : n.args) ensure(a, os, indent, allowed);
    if (!n.named || (allowed && !allowed(id))) return;
    const std::string name = "_t" + std::to_string(next_++);
    os << indent << "const T " << name << " = " << print(id).text << ";\n";
    names_[id] = name;
    if (!scopes_.empty()) scopes_.back().push_back(id);
  }
  // Names `id` (a named term) by a variable the caller declares and keeps up to date.
  void bind(int id, const std::string& name) { names_[id] = name; }
  // Coordinates read through a table (a repeated block's function): q[c] prints as
  // q[_i[slot[c]]], and likewise qd.
  void read_through(const std::vector<int>* slot) { slot_ = slot; }
  bool named(int id) const { return !names_[id].empty(); }
  // The text of a node whose named terms are in scope.
  std::string text(int id) { return id == Program::kZero ? "T(0)" : print(id).text; }
  std::string atom_text(int id) { return id == Program::kZero ? "T(0)" : atom(id); }
  // Terms printed between open_scope and close_scope go out of scope at the close.
  void open_scope() { scopes_.emplace_back(); }
  void close_scope() {
    for (int id : scopes_.back()) names_[id].clear();
    scopes_.pop_back();
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

  std::string index(int c) const {
    return slot_ ? "_i[" + std::to_string((*slot_)[c]) + "]" : std::to_string(c);
  }

  Printed input(const Node& n) {
    switch (n.input.kind) {
      case InputKind::kQ: return {"q[" + index(n.input.index) + "]", kAtom};
      case InputKind::kQd: return {"qd[" + index(n.input.index) + "]", kAtom};
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
    if (negative_term(id)) return {true, product(p_.nodes[id], /*negate_coefficient=*/true)};
    return {false, print(id)};
  }
  // Whether a sum's term is printed as a subtraction: an unnamed product with a negative
  // coefficient.
  bool negative_term(int id) const {
    const Node& n = p_.nodes[id];
    if (!names_[id].empty() || n.kind != OpKind::kMul || n.args.empty()) return false;
    const Node& c = p_.nodes[n.args[0]];
    return c.kind == OpKind::kConst && GiNaC::is_a<GiNaC::numeric>(c.exact) &&
           GiNaC::ex_to<GiNaC::numeric>(c.exact).is_negative();
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
        // `q[3] - q[6]`, not `-q[6] + q[3]`: a negative first term swaps with a positive
        // second, which leaves every rounding as it was (a + b == b + a, and the rest of the
        // sum still adds to their sum).
        std::vector<int> args = n.args;
        if (args.size() >= 2 && negative_term(args[0]) && !negative_term(args[1]))
          std::swap(args[0], args[1]);
        std::string s;
        for (std::size_t a = 0; a < args.size(); ++a) {
          auto [negative, term] = signed_term(args[a]);
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
      case OpKind::kMotionLaw:  // the motion_law kernel (kernels/motion_law.hpp)
        return {"_motion_law(" + std::to_string(n.law) + ", " + std::to_string(n.order) + ", " +
                    print(n.args[0]).text + ")",
                kAtom};
      case OpKind::kSelect:  // the piecewise kernel (kernels/piecewise.hpp)
        return {"_select(" + print(n.args[0]).text + ", " + print(n.args[1]).text + ", " +
                    print(n.args[2]).text + ")",
                kAtom};
      case OpKind::kFloor:
        return call("_floor_re");
      case OpKind::kDriverInput:  // named by emit_header (input_members)
        return {"T(p.@in" + std::to_string(n.table) + "." + std::to_string(n.order) + "@)", kAtom};
      case OpKind::kTable:  // renumbered per header by with_expression_kernels
        return {table_token(n.table) + "(" + std::to_string(n.order) + ", " +
                    print(n.args[0]).text + ")",
                kAtom};
    }
    return {"?", kAtom};
  }

  const Program& p_;
  const SymbolTable& symbols_;
  std::vector<std::string> names_;
  int next_ = 0;
  std::vector<std::vector<int>> scopes_;
  const std::vector<int>* slot_ = nullptr;
};

inline std::string idx(int k) { return std::to_string(k); }

template <class Container>
std::string join(const Container& values) {
  std::string s;
  for (const auto& v : values) s += (s.empty() ? "" : ", ") + v;
  return s;
}

// The std functions a program calls, for a using-declaration: unqualified calls then find
// std's overloads for float, double and std::complex, and other scalar types by ADL.
std::string std_functions(const Program& program);


void emit_signature(std::ostringstream& os, const std::string& name, bool with_qd);

// One function, or when the program has more than max_ops operations or max_part_outputs
// outputs (max_ops > 0), private parts that the function calls in order: g++ -O2 takes time
// superlinear in a function's size.
// out_index: the out index of each of the program's outputs (default: k); tail: code that ends
// the public function.
void emit_function(std::ostringstream& os, const char* name, const char* out_size,
                   const Program& program, const SymbolTable& symbols, bool with_qd,
                   int max_ops, const std::vector<int>* out_index = nullptr,
                   const std::string& tail = "");

// `static constexpr int name[rows][columns]`, a table of the repeated pieces (a row of zero
// columns is stored as one 0, which nothing reads).
void emit_table(std::ostringstream& os, const std::string& name,
                const std::vector<std::vector<int>>& rows);



// emit_function for outputs of which some are rolled (roll_outputs): each class's function and
// tables (private), then the function, which evaluates the rest and loops over the classes.
void emit_rolled_function(std::ostringstream& os, const char* name, const char* out_size,
                          const RolledOutputs& ro, const SymbolTable& symbols, bool with_qd,
                          int max_ops);

// emit_function, or emit_rolled_function when some constraints repeat (roll_min > 0).
void emit_function_rolled_if(std::ostringstream& os, const char* name, const char* out_size,
                             const Program& program, const std::vector<GiNaC::ex>& exprs,
                             const std::vector<int>& group, const SymbolTable& symbols,
                             bool with_qd, int max_ops, int roll_min);

}  // namespace kinegen::codegen::emit_detail
