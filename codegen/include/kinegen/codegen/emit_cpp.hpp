// The C++ back end: one self-contained header per mechanism (spec section 4).
#pragma once

#include <string>

#include "kinegen/codegen/mechanism.hpp"
#include "kinegen/codegen/program.hpp"
#include "kinegen/codegen/symbolic.hpp"

namespace kinegen::codegen {

inline constexpr const char* kVersion = "0.1.0";

// Which analyses a header supports: position only (phi, phi_q and the block position solver),
// position and velocity (adds nu), or all (adds gamma); the default is all.
enum class Outputs { kPosition, kVelocity, kAll };

struct EmitOptions {
  Outputs outputs = Outputs::kAll;
  // The block solver (structure.hpp) besides the section-4 functions.
  bool block_solver = true;
};

// The generated header's text. Only validated identifiers and numbers from the mechanism reach
// it; the source file is named by its base name, with anything unusual replaced.
std::string emit_header(const Mechanism& mechanism, const SymbolTable& symbols,
                        const SymbolicModel& model, const ModelPrograms& programs);
std::string emit_header(const Mechanism& mechanism, const SymbolTable& symbols,
                        const SymbolicModel& model, const ModelPrograms& programs,
                        const EmitOptions& options);

// Formats a double so that it reads back to the same value (17 significant digits).
std::string format_double(double value);

}  // namespace kinegen::codegen
