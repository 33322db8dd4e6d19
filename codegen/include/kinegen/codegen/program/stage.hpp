// The program stage: symbolic outputs lowered to straight-line programs.
//
// Takes: a SymbolicModel and its SymbolTable (symbolic stage). Gives: Programs (lower: nodes in
// dependency order, common subexpressions shared, constants folded, canonical operand order)
// and ModelPrograms (lower_model: phi, phi_q, nu, gamma and the outputs' programs). Every back
// end prints or runs these nodes in this order, so all round alike. Next: the structure stage,
// the emitter and the in-process evaluator. Also gives partition (partition.hpp): the one rule
// that cuts a sequence of generated code (outputs, blocks, a torn block's assignments) into
// parts of bounded size, for compile time, and CanonicalKey (canonical_key.hpp): the order
// independent of GiNaC's hashes that the lowering and the high-precision reference share.
#pragma once

#include "kinegen/codegen/program/canonical_key.hpp"
#include "kinegen/codegen/program/partition.hpp"
#include "kinegen/codegen/program/program.hpp"
