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

#include "kinegen/codegen/symbolic/symbolic.hpp"

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
  // Tearing (Newton blocks only; empty when the block is not torn): Newton iterates on the
  // `tears` alone. Each `assigned` (row, col) pair is solved explicitly, in order, from the
  // tears, earlier assignments and earlier blocks: the row is linear in col with the constant
  // coefficient `assigned_coefficient` (a numeric Phi_q entry), q[col] = `assigned_value`.
  // The `residuals` (as many as tears) are the rows left for Newton.
  std::vector<int> tears, residuals;
  std::vector<std::pair<int, int>> assigned;
  std::vector<GiNaC::ex> assigned_value, assigned_coefficient;
  bool torn() const { return !assigned.empty(); }
  int newton_size() const {
    return kind != BlockKind::kNewton ? 0
           : torn()                   ? static_cast<int>(tears.size())
                                      : static_cast<int>(block.rows.size());
  }
};

// The BLT order of a model and each block's kind. `plans` is empty when `order.perfect` is
// false.
struct Structure {
  BltOrder order;
  std::vector<BlockPlan> plans;
  int explicit_count() const;
  int newton_count() const;
  int largest_block() const;
  int largest_newton() const;  // the largest system Newton solves (torn blocks: their tears)
};

Structure analyze_structure(const SymbolicModel& model, const SymbolTable& symbols);

const char* to_string(BlockKind kind);

}  // namespace kinegen::codegen
