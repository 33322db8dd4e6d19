// The symbolic stage: the mechanism's equations and their derivatives as GiNaC expressions.
//
// Takes: a Mechanism (model stage). Gives: a SymbolTable (every GiNaC symbol: coordinates,
// velocities, time, parameters, inputs) and a SymbolicModel (derive): Phi(q, t), the
// structural non-zeros of Phi_q, nu = -Phi_t, gamma, q0, the points' offsets, the outputs,
// exact parameter values, the coordinate kinds and the length scale. functions.hpp is the one
// table of the expression language's functions and motion laws. Beside derive, from the same
// pieces (and the Mechanism's ForceSpec): the kinetostatic expressions (forces.hpp:
// derive_forces gives a ForceModel, Q^A and the mass data and reaction points; force_columns)
// the parameter derivatives (sensitivity.hpp: derive_phi_p, derive_output_p) and the
// derivatives the dynamics' tangent needs (tangent.hpp: derive_tangent), which the emitter
// prints and the analysis evaluates. Next: the program stage (lowering) and the
// structure stage (BLT).
#pragma once

#include "kinegen/codegen/symbolic/forces.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"
#include "kinegen/codegen/symbolic/sensitivity.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"
#include "kinegen/codegen/symbolic/tangent.hpp"
