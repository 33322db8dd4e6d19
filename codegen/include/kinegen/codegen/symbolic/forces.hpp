// Kinetostatics, the symbolic half: the applied generalized force Q^A and the mass
// data and reaction points as expressions, and the force columns' names. Beside
// derive(): the emitter prints these and the analysis (analysis/forces.hpp) evaluates them, so
// both take them from here.
//
// Takes: the mechanism, its mass data and loads (ForceSpec), the symbol table and symbolic
// model. Gives: ForceModel (Q^A(q, qd, t) as expressions, the bodies' mass data and the joints'
// points exact, in double and as symbols) and the column names of `analyze --forces`.
#pragma once

#include <ginac/ginac.h>

#include <array>
#include <string>
#include <vector>

#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

// Which rule a constraint follows for its effort and reaction columns (its kind says).
bool is_distance(const Constraint& c);
bool is_expression(const Constraint& c);

// The numbers of the mass data and of the joints' points, in a scalar type T: double for the
// analysis, GiNaC::numeric for the 40-digit reference, GiNaC::ex for generated code.
template <class T>
struct ForceData {
  std::vector<T> mass, inertia;          // per body
  std::vector<std::array<T, 2>> com;     // per body, local
  std::vector<std::array<T, 2>> si, sj;  // per joint and driver (constraints() order)
};

// Q^A as expressions; whoever runs it lowers it (the emitter after folding, ForceSolver as is).
struct ForceModel {
  std::vector<GiNaC::ex> applied;  // Q^A(q, qd, t), nq: gravity and the loads
  // The energy columns of `simulate`: the potential of gravity and the springs (preloads
  // included), V(q), and the generalized force of everything else that does work:
  // `force` and `torque` loads and the dampers, Q^nc(q, qd, t), so that Q^A = -V_q + Q^nc.
  GiNaC::ex potential;
  std::vector<GiNaC::ex> nonconservative;  // nq
  ForceData<GiNaC::ex> exact;      // parameters substituted, exact where they are
  ForceData<double> numbers;       // the same in double
  ForceData<GiNaC::ex> symbolic;   // the same with the parameters as symbols (generated code)
  std::vector<int> row_begin;      // rows of constraint c: [row_begin[c], row_begin[c + 1])
};

// Builds Q^A and evaluates the mass data. Throws InputError for negative or non-finite mass
// data, unknown bodies, expressions that are not allowed (velocities) or not finite.
ForceModel derive_forces(const Mechanism& mechanism, const SymbolTable& symbols,
                         const SymbolicModel& model, const ForceSpec& spec);

// Whether the file gives anything derive_forces reads beyond the defaults (a mass, inertia
// or centre of mass other than "0", gravity, a load): without, there is nothing to check.
bool has_force_input(const ForceSpec& spec);

// Column names added by `analyze --forces`: every driver's effort(s), then every joint's
// reaction (fx, fy, tz), in file order.
std::vector<std::string> force_columns(const Mechanism& mechanism);

}  // namespace kinegen::codegen
