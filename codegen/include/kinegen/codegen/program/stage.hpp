// The program stage: symbolic outputs lowered to straight-line programs.
//
// Takes: a SymbolicModel and its SymbolTable (symbolic stage). Gives: Programs (lower: nodes in
// dependency order, common subexpressions shared, constants folded, canonical operand order)
// and ModelPrograms (lower_model: phi, phi_q, nu, gamma and the outputs' programs). Every back
// end prints or runs these nodes in this order, so all round alike. Next: the structure stage,
// the emitter and the in-process evaluator.
#pragma once

#include "kinegen/codegen/program/program.hpp"
