// The C++ back end: one self-contained header per mechanism.
#pragma once

#include <string>

#include "kinegen/codegen/base/format.hpp"  // format_double
#include "kinegen/codegen/base/version.hpp"  // kVersion
#include "kinegen/codegen/compile/compiled_model.hpp"

namespace kinegen::codegen {

// Which analyses a header supports: position only (phi, phi_q and the block position solver),
// position and velocity (adds nu), or all (adds gamma); the default is all.
enum class Outputs { kPosition, kVelocity, kAll };

// The default of EmitOptions::max_function_ops (kinegen generate --max-function-ops).
inline constexpr int kDefaultMaxFunctionOps = 1000;
// The default of EmitOptions::roll_min (kinegen generate --roll-min).
inline constexpr int kDefaultRollMin = 16;

struct EmitOptions {
  Outputs outputs = Outputs::kAll;
  // The block solver (structure.hpp) besides the section-4 functions.
  bool block_solver = true;
  // Functions with more operations than this are split into private parts that the public
  // function calls in order (g++ -O2 compile time grows superlinearly with a function's size);
  // 0: never split. The block solver is split at block boundaries. See docs/scale.md.
  int max_function_ops = kDefaultMaxFunctionOps;
  // Repeated blocks: Newton blocks that are the same up to which coordinates they read (the
  // loops of a chain) are emitted once, as a function that each of them calls with a table of
  // its coordinates, when at least this many are alike; 0: never. Keeps large models' code,
  // and so their compile time and instruction-cache footprint, from growing with N.
  int roll_min = kDefaultRollMin;
  // The namespace the model's struct lives in (kinegen generate --namespace): two models of
  // the same name need different ones to live in one program.
  std::string name_space = "kinegen::models";
};

// The generated header's text, printed from the compiled model: its programs and, for the
// block solver, its structure() (analyzed once, on first use). Only validated identifiers and
// numbers from the mechanism reach it; the source file is named by its base name, with
// anything unusual replaced. A model built with BuildOptions::fold_params gives a header whose
// parameters are folded into constants (it says so, and keeps Params only for the same API).
std::string emit_header(const CompiledModel& model, const EmitOptions& options = {});

}  // namespace kinegen::codegen
