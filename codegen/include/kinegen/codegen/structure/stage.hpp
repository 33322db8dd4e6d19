// The structure stage: how Phi(q, t) = 0 is solved block by block.
//
// Takes: a SymbolicModel and its SymbolTable (symbolic stage). Gives: a Structure
// (analyze_structure: the block-lower-triangular order from a maximum matching and the
// strongly connected components, and each block's BlockPlan: explicit, guarded, Newton or
// torn) and a BlockProgram (build_block_program: what the block solver computes, as data, one
// lowered program holding every block's solutions, residuals, Jacobian entries, couplings, nu
// and gamma, with the sin/cos cache slots) and a SolverPlan (plan_block_solver: the
// BlockProgram with the classes of repeated blocks and the cuts of a split solver, decided as
// data). Next: the emitter prints the SolverPlan, the analysis stage's BlockInterpreter runs
// the BlockProgram (repeated blocks and parts compute the same values; tests [split]).
#pragma once

#include "kinegen/codegen/structure/block_program.hpp"
#include "kinegen/codegen/structure/solver_plan.hpp"
#include "kinegen/codegen/structure/structure.hpp"
