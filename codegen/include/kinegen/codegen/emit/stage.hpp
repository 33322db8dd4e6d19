// The emit stage: the C++ back end.
//
// Takes: a CompiledModel (compile stage: the mechanism, its symbols, expressions, lowered
// programs and structure) and EmitOptions; from the structure the SolverPlan and BlockProgram
// (structure stage). Nothing from the analysis stage. Gives: one self-contained C++ header per mechanism as a
// std::string (emit_header), carrying the block-solver kernels it calls
// (runtime/include/kinegen/kernels/, embedded at build time). reserved_names.hpp: the names a
// header cannot carry, checked before emitting.
#pragma once

#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "kinegen/codegen/emit/reserved_names.hpp"
