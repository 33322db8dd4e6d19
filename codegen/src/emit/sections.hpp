// Sections of the header that emit_header (emit_cpp.cpp) prints from files of their own.
// Private to the emit stage.
#pragma once

#include <sstream>

#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/codegen/program/program.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen::emit_detail {

// Each row's constraint, numbered in order of first appearance: the groups roll_outputs rolls.
std::vector<int> constraint_groups(const SymbolicModel& model);

// num_params, has_sensitivity, phi_p and solve_sensitivity (emit_sensitivity.cpp).
void emit_sensitivity(std::ostringstream& os, const SymbolTable& symbols,
                      const SymbolicModel& model, const EmitOptions& options);

// The force functions, when the mechanism has masses, inertias or loads (emit_forces.cpp).
void emit_forces(std::ostringstream& os, const Mechanism& m, const SymbolTable& symbols,
                 const SymbolicModel& model, const ModelPrograms& programs,
                 const EmitOptions& options);

}  // namespace kinegen::codegen::emit_detail
