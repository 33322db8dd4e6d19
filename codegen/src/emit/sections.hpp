// Sections of the header that emit_header (emit_cpp.cpp) prints from files of their own.
// Private to the emit stage.
#pragma once

#include <sstream>

#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/codegen/program/program.hpp"
#include "kinegen/codegen/symbolic/forces.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen::emit_detail {

// Each row's constraint, numbered in order of first appearance: the groups roll_outputs rolls.
std::vector<int> constraint_groups(const SymbolicModel& model);

// num_params, has_sensitivity, phi_p and solve_sensitivity (emit_sensitivity.cpp).
void emit_sensitivity(std::ostringstream& os, const CompiledModel& compiled,
                      const EmitOptions& options);

// The force functions, when the mechanism has masses, inertias or loads (emit_forces.cpp).
// trig_slot: each coordinate's slot in the block solver's sin/cos cache (-1: none).
void emit_forces(std::ostringstream& os, const CompiledModel& compiled, const EmitOptions& options,
                 const std::vector<int>& trig_slot);

// A spatial file's branch conditions and its drivers' rows by value for the first solve
// (emit_spatial.cpp).
void emit_spatial(std::ostringstream& os, const CompiledModel& compiled,
                  const EmitOptions& options);

// What emit_dynamics prints from: the force model and mass_at[b], where body b's m, J and A
// com start in _force_geometry's output of geometry_size values (-1: no mass).
struct DynamicsSource {
  const CompiledModel& compiled;
  const Mechanism& m;
  const SymbolTable& symbols;
  const SymbolicModel& model;
  const ForceModel& forces;
  const EmitOptions& options;
  std::vector<int> mass_at;
  int geometry_size;
  const std::vector<int>& trig_slot;  // as emit_forces'
};

// dynamics(), its work space and its exact Jacobians (emit_dynamics.cpp), after
// the force functions they call.
void emit_dynamics(std::ostringstream& os, const DynamicsSource& d);

}  // namespace kinegen::codegen::emit_detail
