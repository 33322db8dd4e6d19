// `kinegen check`: the derivative blocks Phi_q, nu and gamma of the double straight-line
// program against three independent truths at random configurations near q0 (random qd):
// (a) complex-step derivatives of Phi, (b) central differences of Phi with steps relative to
// each coordinate's size, (c) the symbolic expressions evaluated in CLN arithmetic.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "kinegen/codegen/compile/compiled_model.hpp"

namespace kinegen::codegen {

// The values under test. An empty function means the model's own double program, so a test
// can replace one block by a deliberately wrong one and see the check fail.
struct CheckCandidate {
  // Structural non-zeros of Phi_q in ModelPrograms jac_rows/jac_cols order.
  std::function<void(const double* q, double t, double* out)> phi_q_values;
  std::function<void(const double* q, double t, double* out)> nu;
  std::function<void(const double* q, const double* qd, double t, double* out)> gamma;
};

struct CheckOptions {
  int samples = 5;
  unsigned seed = 1;
  double t = 0;
  // Every angle is shifted by 2 pi turns: the same configurations after many revolutions.
  double turns = 0;
  int digits = 40;  // working precision of the CLN method
  CheckCandidate candidate;
};

struct CheckRow {
  std::string block;   // phi_q, nu, gamma
  std::string method;  // complex-step, central-difference, cln-<digits>
  double max_abs = 0;  // largest |candidate - truth|
  double max_rel = 0;  // the same divided by max(1, largest |truth| in the block)
  double bound = 0;    // max_rel must not exceed this
  bool ok() const { return max_rel <= bound; }
};

// One row per block and method, in the order phi_q, nu, gamma; each block's methods in the
// order complex-step, central-difference, cln. Throws UsageError for bad options.
std::vector<CheckRow> check_derivatives(const CompiledModel& model, const CheckOptions& options);

// Each entry of Phi_q: structurally zero, "constant" (no q or t in it) or "varying".
std::string jacobian_structure(const CompiledModel& model);

}  // namespace kinegen::codegen
