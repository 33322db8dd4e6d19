// Structural decomposition of Phi(q, t) = 0, between the symbolic stage and the emitter: the
// incidence of rows on coordinates (the structural non-zeros of Phi_q), a maximum matching,
// and the strongly connected components of the matched graph, which give a block-lower-
// triangular (BLT) order as Modelica tools compute it. Each block depends only on its own and
// earlier blocks' coordinates, so position, velocity and acceleration can be solved block by
// block. Linear in the number of non-zeros (apart from the augmenting-path search); iterative,
// so large models do not exhaust the stack.
#pragma once

#include <ginac/ginac.h>

#include <string>
#include <vector>

#include "kinegen/codegen/symbolic.hpp"

namespace kinegen::codegen {

struct Block {
  std::vector<int> rows;  // constraint rows, ascending
  std::vector<int> cols;  // coordinates, ascending; as many as rows
};

struct BltOrder {
  // False when no perfect matching exists (structurally singular, or nc != nq); then
  // `blocks` is empty and only the dense path applies.
  bool perfect = false;
  std::vector<Block> blocks;              // in solve order
  std::vector<int> row_block, col_block;  // block index of each row / coordinate
};

// Rows and columns of the structural non-zeros: entries (rows[k], cols[k]).
BltOrder blt_order(int nrows, int ncols, const std::vector<int>& rows,
                   const std::vector<int>& cols);

// How a block's position is solved.
enum class BlockKind {
  kExplicit,         // one equation, linear in its coordinate, non-zero constant coefficient
  kExplicitGuarded,  // linear, but the coefficient depends on parameters or earlier q
  kNewton,           // a small dense Newton iteration of the block's size
};

struct BlockPlan {
  Block block;
  BlockKind kind = BlockKind::kNewton;
  // Explicit kinds: q[col] = -rest / coefficient.
  GiNaC::ex coefficient, rest;
};

// The BLT order of a model and each block's kind. `plans` is empty when `order.perfect` is
// false.
struct Structure {
  BltOrder order;
  std::vector<BlockPlan> plans;
  int explicit_count() const;
  int newton_count() const;
  int largest_block() const;
};

Structure analyze_structure(const SymbolicModel& model, const SymbolTable& symbols);

const char* to_string(BlockKind kind);

}  // namespace kinegen::codegen
