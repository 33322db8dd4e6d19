// stop_when's exact rate along the motion, for the simulation's step rule and its search for
// local maxima (docs/dynamics.md, "stop_when").
#pragma once

#include <ginac/ginac.h>

#include <vector>

#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

// The time derivative of model.stop_when along the motion, as pieces: [dg/dt at qdd = 0 and
// at fixed force columns, dg/dqd (nq), dg/dq (nq), dg/d(force column) (one per
// stop_force_columns)], so that g' = [0] + [1..nq] . qdd + the force columns' rates times their
// pieces. All in q, qd, t, the parameters and the force columns (as extra parameters). Empty
// when a function in g has no derivative the expression language can write.
std::vector<GiNaC::ex> stop_when_rate(const SymbolicModel& model, const SymbolTable& symbols);

}  // namespace kinegen::codegen
