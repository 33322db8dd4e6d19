// The block solver as the emitter prints it: the structure, its block program, the classes of
// repeated blocks and where a split solver is cut. All of it is decided here, as plain data,
// so that the emitter only prints (emit/block_solver.cpp) and a test can read the decisions.
// None of them changes what is computed: repeated blocks run the first block's expressions on
// their own coordinates, and parts run the whole solver's statements in order.
#pragma once

#include <map>
#include <memory>
#include <utility>
#include <vector>

#include "kinegen/codegen/program/partition.hpp"
#include "kinegen/codegen/structure/block_program.hpp"
#include "kinegen/codegen/structure/structure.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

struct SolverPlan;

// Newton blocks that are the same up to a renaming of the coordinates they read (the loops of
// a chain). A block's coordinate table lists its own coordinates (in order), then the others
// it reads (its expressions' q and qd, and the coordinates its rows couple to), ascending. Two
// blocks are alike when, with the k-th coordinate of each table renamed to the model's k-th,
// their structure and every expression agree exactly.
struct RepeatedBlocks {
  std::vector<int> blocks;               // ascending; the first is the one printed
  std::vector<std::vector<int>> coords;  // per member: its coordinate table
  std::vector<std::vector<int>> slots;   // per member: its trig cache slots, in alone's order
  // The first block as a model of its own (one block, no classes, no parts), whose functions
  // every member calls with its tables.
  std::shared_ptr<const SolverPlan> alone;
};

// A torn block split into parts: ranges of its assigned coordinates (indices into
// plan.assigned) for the parts of its Newton loop and of its rates; empty: not split.
struct TornParts {
  PartRanges position, rates;
  std::map<int, std::vector<char>> dependency;  // tear_dependency
  // Its coordinates with a trig slot, whose sin and cos (rotated by the Newton updates) live
  // in the caller's _sc from index 2 * trig_first on, for the parts and the rates.
  std::vector<int> rotated;
  int trig_first = 0;
};

struct SolverPlan {
  Structure structure;
  BlockProgram program;
  // Repeated blocks (roll_min > 0): the classes of at least roll_min members, and per block its
  // class and its row there, or -1.
  std::vector<RepeatedBlocks> repeated;
  std::vector<int> class_of, member_of;
  // A split solver (max_ops > 0): runs of consecutive blocks [first, second), one function
  // each (empty: one function); per block, its torn parts; the rows of _torn_trig
  // ({coordinate, trig slot}) of the split torn blocks' rotated coordinates.
  PartRanges ranges;
  std::vector<TornParts> torn_parts;
  std::vector<std::vector<int>> torn_trig;
  bool torn_any = false;  // some torn block is split

  bool torn_split(std::size_t b) const {
    return !torn_parts.empty() && !torn_parts[b].position.empty();
  }
  // Every output of `program` block b's functions read.
  std::vector<int> block_outputs(std::size_t b) const;
  // What a split torn block's own functions (not its parts) read, as nodes: the residual rows,
  // their Phi_q entries and couplings, and their rates.
  std::vector<int> torn_host_outputs(std::size_t b, bool position = true, bool rates = true) const;
  std::map<int, std::vector<char>> tear_dependency(std::size_t b) const {
    return codegen::tear_dependency(structure.plans[b], program.torn_jacobian[b]);
  }
};

// The entries of `entries` in row r, in order.
std::vector<std::pair<std::pair<int, int>, int>> row_entries(
    const std::map<std::pair<int, int>, int>& entries, int r);

// Builds the block program of `st`, finds the classes of at least roll_min repeated blocks
// (0: none) and cuts the solver into parts of about max_ops operations (0: never; the rule of
// partition.hpp).
SolverPlan plan_block_solver(const SymbolicModel& model, const SymbolTable& symbols,
                             const Structure& st, int max_ops, int roll_min);
// The same from `st`'s block program built already (CompiledModel::block_program()).
SolverPlan plan_block_solver(const SymbolicModel& model, const SymbolTable& symbols,
                             const Structure& st, BlockProgram program, int max_ops, int roll_min);

}  // namespace kinegen::codegen
