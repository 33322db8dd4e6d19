// The in-process back end: runs a straight-line program on any scalar type (double for
// analysis, std::complex<double> for complex-step checks), in exactly the order the emitted
// C++ computes it, so both give the same bits.
#pragma once

#include <cmath>
#include <complex>
#include <cstdlib>
#include <limits>
#include <vector>

#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/program/program.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"
#include "kinegen/kernels/piecewise.hpp"
#include "kinegen/kernels/spline.hpp"

namespace kinegen::codegen {

template <class T>
class ProgramEvaluator {
 public:
  explicit ProgramEvaluator(const Program& program)
      : program_(&program), values_(program.nodes.size()) {}

  // Inputs by kind; `qd` may be null when the program does not read it. Writes one value per
  // program output. Allocates nothing.
  void run(const T* q, const T* qd, T t, const T* params, T* out) {
    const auto& nodes = program_->nodes;
    for (std::size_t k = 0; k < nodes.size(); ++k)
      values_[k] = node_value(nodes, k, values_.data(), q, qd, t, params, inputs_);
    for (std::size_t o = 0; o < program_->outputs.size(); ++o) {
      const int id = program_->outputs[o];
      out[o] = id == Program::kZero ? T(0) : values_[id];
    }
  }

  // The input drivers' values (`f: input`, and the free coordinates, which are inputs
  // too): 3 per driver of Mechanism::drivers, its value, rate and acceleration, as
  // the generated Params members NAME, NAME_v and NAME_a. Not owned; null reads 0.
  void set_inputs(const T* inputs) { inputs_ = inputs; }

  // Node k of `nodes` from the values of the nodes before it, as the emitted C++ computes it:
  // the one evaluation of a node that run() and the in-process block solver share.
  static T node_value(const std::vector<Node>& nodes, std::size_t k, const T* values, const T* q,
                      const T* qd, T t, const T* params, const T* inputs = nullptr) {
    using std::pow;
    const Node& n = nodes[k];
    const auto arg = [&](int a) { return values[n.args[a]]; };
    T v{};
    switch (n.kind) {
      case OpKind::kConst:
        v = T(n.value);
        break;
      case OpKind::kInput:
        switch (n.input.kind) {
          case InputKind::kQ: v = q[n.input.index]; break;
          case InputKind::kQd: v = qd[n.input.index]; break;
          case InputKind::kT: v = t; break;
          case InputKind::kParam: v = params[n.input.index]; break;
        }
        break;
      case OpKind::kAdd:
        v = arg(0);
        for (std::size_t a = 1; a < n.args.size(); ++a) v += values[n.args[a]];
        break;
      case OpKind::kMul: {
        bool have = false;
        for (int a : n.args) {
          if (is_divisor(nodes[a])) continue;
          v = have ? v * values[a] : values[a];
          have = true;
        }
        if (!have) v = T(1);
        for (int a : n.args)
          if (is_divisor(nodes[a])) v = v / power(values[nodes[a].args[0]], -nodes[a].exponent);
        break;
      }
      case OpKind::kPowInt:
        v = n.exponent > 0 ? power(arg(0), n.exponent) : T(1) / power(arg(0), -n.exponent);
        break;
      case OpKind::kPow: v = pow(arg(0), arg(1)); break;
      case OpKind::kMotionLaw:
        v = kernels::motion_law(n.law, n.order, arg(0));
        break;
      case OpKind::kSelect:
        v = kernels::select_piece(arg(0), arg(1), arg(2));
        break;
      case OpKind::kFloor:
        v = kernels::floor_re(arg(0));
        break;
      case OpKind::kDriverInput:
        // Without inputs (eval and check; analyze requires a table), 0, as in a default Params
        // of generated code.
        v = inputs ? inputs[3 * n.table + n.order] : T(0);
        break;
      case OpKind::kTable: {
        const Spline& s = registered_table(n.table);
        v = kernels::SplineKernel::_table(s.t.data(), s.y.data(), s.m.data(),
                                          static_cast<int>(s.t.size()),
                                          s.periodic ? s.period : 0.0, s.rise, n.order, arg(0));
        break;
      }
      default:  // sqrt, sin, ... (functions.hpp)
        v = apply_function(n.kind, arg(0));
        break;
    }
    return v;
  }

 private:
  // x^n for n >= 1 as the emitted code writes it: left-to-right products, or pow beyond.
  static T power(const T& x, int n) {
    using std::pow;
    if (n > kMaxUnrolledPower) return pow(x, T(n));
    T r = x;
    for (int k = 1; k < n; ++k) r = r * x;
    return r;
  }

  const Program* program_;
  std::vector<T> values_;
  const T* inputs_ = nullptr;
};

}  // namespace kinegen::codegen
