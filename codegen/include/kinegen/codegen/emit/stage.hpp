// The emit stage: the C++ back end.
//
// Takes: the Mechanism, SymbolTable, SymbolicModel and ModelPrograms (the stages before it), the
// caller's Structure (CompiledModel::structure(); analyzed here only for callers without one)
// and EmitOptions; from them the SolverPlan and BlockProgram (structure stage), the force and
// sensitivity expressions (symbolic stage: symbolic/forces.hpp, symbolic/sensitivity.hpp;
// nothing from the analysis stage). Gives: one self-contained C++ header per mechanism as a
// std::string (emit_header), carrying the block-solver kernels it calls
// (runtime/include/kinegen/kernels/, embedded at build time). reserved_names.hpp: the names a
// header cannot carry, checked before emitting.
#pragma once

#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "kinegen/codegen/emit/reserved_names.hpp"
