// The lowered programs the consumers read beyond ModelPrograms: the forces, the free items,
// stop_when, the dynamics' tangent and the parameter derivatives. CompiledModel (compile
// stage) lowers each once, on first use, and both consumers take them from it.
#pragma once

#include <ginac/ginac.h>

#include <cstddef>
#include <vector>

#include "kinegen/codegen/program/program.hpp"
#include "kinegen/codegen/symbolic/forces.hpp"
#include "kinegen/codegen/symbolic/tangent.hpp"

namespace kinegen::codegen {

// A ForceModel's expressions lowered: Q^A, its non-conservative part Q^nc and the potential V
// (one output), in q, qd, t.
struct ForcePrograms {
  Program applied, nonconservative, potential;
};

// The free items' coordinates z (the `free:` drivers'), in q, qd, t: their values, their rates,
// the gradient dz/dq (nf x nq, row-major) and the part of zdd without qdd (sum over c of
// d(zd)/dq_c qd_c), each its own program.
struct FreePrograms {
  Program values, rates, gradient, a0;
};

// stop_when's g, then its rate's pieces (stop_when_rate) when it has them, in one program.
struct StopPrograms {
  Program program;
  std::size_t size = 0;  // outputs: g and the rate's pieces
  bool has_rate = false;
};

// The dynamics' tangent (symbolic/tangent.hpp) with Q^A, in one program so that the pieces
// share their common terms: Phi_qq, nu_q, gamma_q, gamma_qd, Phi_w, nu_w, gamma_w, Q^A, Q^A_q,
// Q^A_qd and Q^A_w, piece p's outputs from begin[p] to begin[p + 1]. The command line's
// Linearizer evaluates it, a header's dynamics_jacobians prints it: one order for both.
struct TangentProgram {
  TangentModel tangent;
  std::vector<int> begin;
  Program program;
};

// Phi's (and, where asked, the outputs') derivatives by the parameters `params`: Phi_p as
// expressions (derive_phi_p's order, nc * np) and lowered, O_p lowered (derive_output_p's).
struct ParameterPrograms {
  std::vector<GiNaC::ex> phi_p_expressions;
  Program phi_p, output_p;
};

// A force model lowered, its parameters substituted first when `fold` (--fold-params) holds.
ForcePrograms compile_forces(const ForceModel& forces, const SymbolTable& symbols,
                             const SymbolicModel& model, bool fold);

}  // namespace kinegen::codegen
