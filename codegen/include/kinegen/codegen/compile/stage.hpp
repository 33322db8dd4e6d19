// The compile stage: the whole product of the pipeline, owned in one place.
//
// Takes: a mechanism file or a Mechanism, parameter overrides and BuildOptions. Runs the stages
// before it (model, symbolic, program, structure) and keeps what they give: the Mechanism, the
// SymbolTable, the SymbolicModel, the ModelPrograms and the Structure (computed on first use).
// Gives: a CompiledModel (compiled_model.hpp). Next: both consumers read it, neither derives
// nor lowers at the point of use: the emitter prints it (emit_header), the analyses evaluate it.
#pragma once

#include "kinegen/codegen/compile/compiled_model.hpp"
