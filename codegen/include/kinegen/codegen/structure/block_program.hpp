// The block program: what the block solver computes, as data, between the structure stage
// (structure.hpp: the BLT blocks and each block's plan) and its two users. The C++ emitter
// prints it (emit_cpp.cpp: solve_position, solve_step, ...); the in-process block solver
// (block_interpreter.hpp) runs it, so `kinegen analyze` and generated code compute the same
// numbers. One lowered program holds every expression the block functions need (explicit
// solutions, residuals, Jacobian entries, couplings to earlier blocks, nu, gamma), so terms
// are shared between blocks and between the position and rate phases.
#pragma once

#include <map>
#include <utility>
#include <vector>

#include "kinegen/codegen/program/program.hpp"
#include "kinegen/codegen/structure/structure.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

// A block's rate rows (Phi_q x = rhs on the block), as outputs of BlockProgram::program.
struct BlockRates {
  std::vector<int> jbb;                                     // row-major k x k (not torn)
  std::map<std::pair<int, int>, int> tjac;                  // torn blocks: (row, col) -> output
  std::vector<std::vector<std::pair<int, int>>> coupling;  // per row: (earlier col, output)
  std::vector<int> nu, gamma;                               // per row
};

struct BlockProgram {
  // The outputs before lowering (the emitter compares blocks by them), and lowered.
  std::vector<GiNaC::ex> exprs;
  Program program;
  // Position outputs of block b: [position_first[b], next block's first or position_end).
  // Explicit: the value. Guarded: coefficient, rest. Newton: the rows' residuals, then the
  // row-major Jacobian. Torn: the assigned values, the residual rows, then the block's
  // non-zero Phi_q entries (torn_jacobian[b]: (row, col) -> output).
  std::vector<int> position_first;
  int position_end = 0;
  std::vector<std::map<std::pair<int, int>, int>> torn_jacobian;
  std::vector<BlockRates> rates;
  // Per node: the last block whose coordinates it reads (-1: none).
  std::vector<int> level;
  // Per coordinate: its sin / cos node (of the plain coordinate), or -1, and its slot in the
  // sin/cos cache (-1: none); 3 values per slot.
  std::vector<int> sin_of, cos_of, trig_slot;
  int trig_slots = 0;
  // Per node: read by a position output.
  std::vector<char> in_position;

  int output(int k) const { return program.outputs[k]; }
  // The end of block b's position outputs.
  int position_last(std::size_t b) const {
    return b + 1 < position_first.size() ? position_first[b + 1] : position_end;
  }
};

// Which tears each of a torn block's coordinates depends on (dependency[col][j]), from the
// block's non-zero Phi_q entries (BlockProgram::torn_jacobian).
std::map<int, std::vector<char>> tear_dependency(
    const BlockPlan& plan, const std::map<std::pair<int, int>, int>& entries);

BlockProgram build_block_program(const SymbolicModel& model, const SymbolTable& symbols,
                                 const Structure& st);

}  // namespace kinegen::codegen
