// Cutting generated code into parts for compile time (docs/scale.md, "Split functions"):
// g++ -O2 takes time superlinear in a function's size, so the generated functions (their
// outputs), the block solver (its runs of blocks) and a torn block (its assigned coordinates)
// are cut into consecutive parts by this one rule.
#pragma once

#include <algorithm>
#include <functional>
#include <utility>
#include <vector>

#include "kinegen/codegen/program/program.hpp"

namespace kinegen::codegen {

// At most max_ops / kOpsPerStore stores per part. g++ -O2 checks each store against the earlier
// stores of its function (value numbering looks for a redundant store, up to 1000 alias queries
// each), so the time per part grows with the square of its stores: a Jacobian part of 1000
// operations has about 1600 of them. See docs/scale.md.
constexpr int kOpsPerStore = 5;
inline int max_part_outputs(int max_ops) { return std::max(1, max_ops / kOpsPerStore); }
// Whether a generated function of `program` is split into parts (max_ops > 0: the limit).
inline bool split_function(const Program& program, int max_ops) {
  return max_ops > 0 && (program.operation_count() > max_ops ||
                         static_cast<int>(program.outputs.size()) > max_part_outputs(max_ops));
}

// What an item of a sequence adds to its part: the expression trees of `nodes` (nodes of
// `program`; kZero for none), each node counted once per part and constants and inputs free,
// plus `ops` operations and `stores` stores.
struct PartCost {
  std::vector<int> nodes;
  int ops = 0;
  int stores = 0;
};

// Consecutive ranges [first, second) of the items 0..n-1: a part ends with the item that brings
// its operations to max_ops or its stores to max_part_outputs(max_ops). An item is never split.
using PartRanges = std::vector<std::pair<int, int>>;
PartRanges partition(const Program& program, int max_ops, int n,
                     const std::function<PartCost(int)>& cost);

// A part of a program split for compile time: a contiguous range of outputs and every node they
// read, in the program's order. Nodes keep their kind, arguments and `named` flags, so a part
// evaluates each output exactly as the whole program does; terms shared with other parts are
// recomputed.
struct ProgramPart {
  int first_output = 0;
  Program program;
};

// Splits `program` into parts of about max_ops operations or max_part_outputs outputs each
// (partition.hpp; one output's terms are never split).
std::vector<ProgramPart> split_program(const Program& program, int max_ops);

}  // namespace kinegen::codegen
