// Parameter sensitivities, the symbolic half: the derivatives by parameter symbols of
// the same Phi and outputs that derive() differentiates by coordinates. The emitter prints
// Phi_p and the analysis (analysis/sensitivity.hpp) lowers and evaluates both, so both take
// them from here.
#pragma once

#include <ginac/ginac.h>

#include <vector>

#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

// dPhi/dp for each parameter index in `params`, symbolic: output k * nc + r is dPhi_r/dp_k.
// Beside derive(): the same Phi, differentiated by parameter symbols instead of coordinates.
std::vector<GiNaC::ex> derive_phi_p(const SymbolicModel& model, const SymbolTable& symbols,
                                    const std::vector<int>& params);

// The outputs' explicit dO/dp for each parameter index in `params` (np x outputs,
// parameter-major: output k * outputs + o is dO_o/dp_k), then O_q (outputs x nq, row-major).
std::vector<GiNaC::ex> derive_output_p(const SymbolicModel& model, const SymbolTable& symbols,
                                       const std::vector<int>& params);

}  // namespace kinegen::codegen
