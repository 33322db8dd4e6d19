// The straight-line program: symbolic outputs lowered to a list of operations in dependency
// order, with common subexpressions shared (GiNaC has no CSE; this one keys on GiNaC's
// structural order), constant subtrees folded to one literal, and zero outputs dropped.
// Both back ends consume it: the C++ emitter and the in-process evaluator.
#pragma once

#include <ginac/ginac.h>

#include <cstddef>
#include <string>
#include <vector>

#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

enum class OpKind {
  kConst,   // a number: `value` (double) and `exact`
  kInput,   // q[k], qd[k], t or a parameter
  kAdd,     // sum of args
  kMul,     // product of args
  kPowInt,  // args[0] ^ exponent (integer, non-zero, not 1)
  kPow,     // args[0] ^ args[1]
  kSqrt,
  kSin,
  kCos,
  kTan,
  kAsin,
  kAcos,
  kAtan,
  kExp,
  kLog,
  kMotionLaw,    // d^order/dx^order of motion law `law` at args[0] (kernels/motion_law.hpp)
  kSelect,       // re(args[0]) < 0 ? args[1] : args[2] (a driver's pieces, kernels/piecewise.hpp)
  kFloor,        // floor(re(args[0])) (whole periods, kernels/piecewise.hpp)
  kDriverInput,  // d^order/dt^order of input driver `table` (Params members)
  kTable,  // d^order/dx^order of table `table` (registered_table) at args[0] (kernels/spline.hpp)
};

struct Node {
  OpKind kind = OpKind::kConst;
  std::vector<int> args;
  int exponent = 0;   // kPowInt
  int law = 0, order = 0;  // kMotionLaw; order also kTable
  int table = -1;          // kTable: its number in table.hpp's registry; kDriverInput: driver
  double value = 0;   // kConst
  GiNaC::ex exact;    // kConst: the exact (or high-precision) value
  Input input{InputKind::kT, 0};  // kInput
  int uses = 0;       // references from other nodes and outputs
  // Computed once into a named intermediate term (`_tK`) rather than inlined where used:
  // operations used more than once, and bases of integer powers (x*x reads x twice).
  bool named = false;
};

// Whether a product's argument is divided by rather than multiplied: an inlined negative
// integer power. Both back ends follow this, so they round identically.
inline bool is_divisor(const Node& arg) {
  return arg.kind == OpKind::kPowInt && arg.exponent < 0 && !arg.named;
}

// Integer powers up to this magnitude become repeated products; larger ones call pow.
inline constexpr int kMaxUnrolledPower = 8;

// A value that is a compile-time constant or a node.
struct Program {
  std::vector<Node> nodes;   // in dependency order: args precede their users
  std::vector<int> outputs;  // node per output; kZero for an identically zero output
  static constexpr int kZero = -1;

  // Whether the program reads any input of this kind (for unused-argument handling).
  bool reads(InputKind kind) const;
  // Nodes that are computed (not inputs, not constants).
  int operation_count() const;
};

// Lowers `outputs` to one program; shared subexpressions become shared nodes.
Program lower(const std::vector<GiNaC::ex>& outputs, const SymbolTable& symbols);

// The programs of one mechanism: what both back ends need.
struct ModelPrograms {
  int nq = 0, nc = 0;
  std::vector<int> jac_rows, jac_cols;
  Program phi, phi_q, nu, gamma;
  // Outputs: their values (q, t; q, qd, t for one that reads velocities); output_rates:
  // the rates, then the accelerations at qdd = 0, then O_q (outputs x nq, row-major), then
  // O_qd where an output reads velocities (output_rate_expressions), all in q, qd, t.
  int num_outputs = 0;
  Program outputs, output_rates;
  std::vector<bool> output_reads_velocity;  // SymbolicModel's
};

// The concatenation output_rates lowers: rates, a0, O_q, and O_qd when an output reads
// velocities (SymbolicModel's output fields).
std::vector<GiNaC::ex> output_rate_expressions(const SymbolicModel& model);

// Each output's value, v and a from `values` (the outputs' values) and `rates` (what
// output_rate_expressions lists, evaluated) at the accelerations qdd: v = rate + O_qd qdd and
// a = `none` for an output that reads velocities (its a would need the jerk), else
// v = rate and a = a0 + O_q qdd. One assembly for the double and the reference rows.
template <class T, class Row>
void assemble_outputs(const std::vector<bool>& reads_velocity, int nq, const T* values,
                      const T* rates, const T* qdd, const T& none, std::vector<Row>& out) {
  const int n = static_cast<int>(reads_velocity.size());
  const T* a0 = rates + n;
  const T* by_q = rates + 2 * n;
  const T* by_qd = by_q + static_cast<std::size_t>(n) * nq;
  out.clear();
  for (int o = 0; o < n; ++o) {
    const bool velocity = reads_velocity[o];
    const T* grad = (velocity ? by_qd : by_q) + static_cast<std::size_t>(o) * nq;
    T sum = velocity ? rates[o] : a0[o];
    for (int k = 0; k < nq; ++k) sum = sum + grad[k] * qdd[k];
    out.push_back(velocity ? Row{values[o], sum, none} : Row{values[o], rates[o], sum});
  }
}

ModelPrograms lower_model(const SymbolicModel& model, const SymbolTable& symbols, int nq);

}  // namespace kinegen::codegen
