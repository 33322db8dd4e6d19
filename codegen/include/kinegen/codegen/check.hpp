// `kinegen check`: the symbolic Phi_q, nu and gamma against numeric derivatives of Phi at
// random configurations near q0.
#pragma once

#include <string>
#include <vector>

#include "kinegen/codegen/model.hpp"

namespace kinegen::codegen {

struct CheckOptions {
  int samples = 5;
  unsigned seed = 1;
  double t = 0;
};

struct CheckRow {
  std::string block;   // phi_q, nu, gamma
  std::string method;  // complex-step, central-difference
  double max_abs = 0;  // largest |symbolic - numeric|
  double max_rel = 0;  // the same divided by max(1, largest |numeric| in the block)
  double bound = 0;    // max_rel must not exceed this
  bool ok() const { return max_rel <= bound; }
};

std::vector<CheckRow> check_derivatives(const CompiledModel& model, const CheckOptions& options);

// Each structural non-zero of Phi_q: "constant" (no q or t in it) or "varying".
std::string jacobian_structure(const CompiledModel& model);

}  // namespace kinegen::codegen
