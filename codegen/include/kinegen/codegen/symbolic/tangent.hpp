// The tangent of the minimal-coordinates dynamics, the symbolic half: the exact
// derivatives that linearizing M qdd + Phi_q^T lambda = Q^A, Phi = 0 about a solved
// state needs, beyond Phi_q. With them the dynamics tangent kernel (kernels/linearize.hpp)
// gives d(zdd)/dz, d(zdd)/dzd and d(zdd)/du through solves with Phi_q alone: the
// velocity residual's q-derivative (Phi_q qd)_q - nu_q is phi_qq contracted with qd,
// the acceleration residual's (Phi_q qdd)_q - gamma_q and -gamma_qd likewise, and
// (Phi_q^T lambda)_q is phi_qq contracted with lambda. The run-time inputs (the free items'
// z, zd, zdd, an input driver's value, rate and acceleration, a load's input) enter through
// their slots (Mechanism::input_slots), as generated code reads them from Params.
//
// Takes: the mechanism, its symbols, its SymbolicModel and ForceModel. Gives: TangentModel,
// sparse matrices of expressions (structural non-zeros only) that the analysis lowers and
// evaluates and generated code prints.
#pragma once

#include <ginac/ginac.h>

#include <vector>

#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/codegen/symbolic/forces.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

// A sparse matrix of expressions: its structural non-zeros, row by row.
struct SparseExpr {
  int rows = 0, cols = 0;
  std::vector<int> row, col;
  std::vector<GiNaC::ex> value;
  void add(int r, int c, const GiNaC::ex& v) {
    if (v.is_zero()) return;
    row.push_back(r);
    col.push_back(c);
    value.push_back(v);
  }
};

// Second derivatives of Phi: d^2 Phi_row / dq_j dq_k for j <= k (the symmetric entry once).
struct HessianExpr {
  std::vector<int> row, j, k;
  std::vector<GiNaC::ex> value;
};

struct TangentModel {
  HessianExpr phi_qq;                // in q, t
  SparseExpr nu_q;                   // nc x nq: d nu / dq, in q, t
  SparseExpr gamma_q, gamma_qd;      // nc x nq: d gamma / dq, d gamma / dqd, in q, qd, t
  SparseExpr phi_w, nu_w, gamma_w;   // nc x input slots: d/d(a run-time input's slot)
  SparseExpr applied_q, applied_qd;  // nq x nq: d Q^A / dq, d Q^A / dqd
  SparseExpr applied_w;              // nq x input slots: d Q^A / d(slot)
};

TangentModel derive_tangent(const Mechanism& mechanism, const SymbolTable& symbols,
                            const SymbolicModel& model, const ForceModel& forces);

}  // namespace kinegen::codegen
