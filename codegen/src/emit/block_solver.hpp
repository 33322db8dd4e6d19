// The emit stage's block solver: the solve_position, solve_velocity, solve_acceleration and
// solve_step functions (and their parts and repeated blocks) printed from the structure
// stage's SolverPlan (its BlockProgram, repeated blocks and parts), statement for statement
// what the in-process BlockInterpreter runs.
// Private to the emit stage; emit_cpp.cpp lays the header out around it.
#pragma once

#include <memory>
#include <sstream>

#include "kinegen/codegen/structure/solver_plan.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen::emit_detail {

class BlockEmitter;

// The block functions of one model, printed into the streams given.
class BlockSolverPrinter {
 public:
  // `plan` must outlive the printer.
  BlockSolverPrinter(const SymbolicModel& model, const SymbolTable& symbols,
                     const SolverPlan& plan);
  ~BlockSolverPrinter();
  int trig_cache_size() const;
  // solve_step keeps its factors for solve_forces (a header with forces).
  void keep_step_factors();
  // solve_position and solve_step check _branches_hold at the solved q (spatial files).
  void check_branches();
  void emit_step_factors(std::ostringstream& os) const;
  void emit_position(std::ostringstream& os);
  void emit_motion(std::ostringstream& os, bool velocity, bool acceleration);
  void emit_step(std::ostringstream& os);
  // The functions of the repeated blocks and their coordinate tables (private members).
  void emit_rolls(std::ostringstream& os, bool velocity, bool acceleration);

 private:
  std::unique_ptr<BlockEmitter> impl_;
};

}  // namespace kinegen::codegen::emit_detail
