// What the analysis time loop (analysis.cpp) and its diagnoses (diagnosis.cpp) share: the
// solvers on the model's programs and the messages that name the constraints involved.
// Private to the analysis stage.
#pragma once

#include <kinegen/solver.hpp>
#include <kinegen/sparse_solver.hpp>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"

namespace kinegen::codegen::analysis_detail {

// ProgramSystem whose nu can be replaced by a given right-hand side: the solver's velocity
// call at the same (q, t) then solves Phi_q x = rhs with the factorization it already holds,
// which is how sensitivities reuse it without a solver interface of their own.
class RhsSystem : public ProgramSystem {
 public:
  explicit RhsSystem(const CompiledModel& model)
      : ProgramSystem(model), kinds_(&model.symbolic().coordinate_kinds) {}
  // What coordinate k measures (the first solve's continuation steps by it).
  CoordinateKind coordinate_kind(int k) const { return (*kinds_)[k]; }
  void nu(const double* q, double t, double* out) const {
    if (rhs_)
      std::copy(rhs_, rhs_ + nc(), out);
    else
      ProgramSystem::nu(q, t, out);
  }
  void use_rhs(const double* rhs) { rhs_ = rhs; }

 private:
  const std::vector<CoordinateKind>* kinds_;
  const double* rhs_ = nullptr;
};

using Solver = BasicSolver<RhsSystem>;
using LargeSolver = SparseSolver<RhsSystem>;

// The sparse path names the constraints behind a singular Phi_q (a dense SVD) only up to this
// many coordinates: the diagnosis runs only on failure, but costs O(nq^2) memory and O(nq^3)
// time (JacobiSVD: about 6 s at nq = 600).
constexpr int kMaxDiagnosedNq = 400;

// Phi_q at (q, t), dense.
Eigen::MatrixXd jacobian_at(const CompiledModel& model, const Eigen::VectorXd& q, double t);

// The constraints behind a (near-)singular Phi_q: rows that carry weight in the left singular
// vectors of its smallest singular values (those within a factor 10 of the smallest, and
// always the smallest), with the scaled condition estimate. rows and cols: the submatrix to
// look at (a failed block's: its rows depend on its own and earlier blocks' coordinates only,
// so later blocks' unsolved values do not enter), or empty for all of Phi_q.
std::string singular_rows(const CompiledModel& model, const Eigen::MatrixXd& jac,
                          std::vector<int> rows = {}, std::vector<int> cols = {});

std::string largest_residual(const CompiledModel& model, const Eigen::VectorXd& q, double t);

// After a non-finite value: which of Phi, Phi_q, nu and gamma is not finite at (q, qd, t)
// (the last solved state, so that only t is new), in which rows, named: a driver's law, a
// table or a parameter beyond a double there. "" when all are finite (then the solve's own
// arithmetic overflowed).
std::string nonfinite_rows(const CompiledModel& model, const Eigen::VectorXd& q,
                           const Eigen::VectorXd& qd, double t);

// At the assembled configuration: the rank of Phi_q, and the equations that repeat earlier
// ones. Consistent redundancy is solved by least squares with a warning (an error under
// --strict); a rank below nq is left to the solver, which reports it as singular.
void check_redundancy(const CompiledModel& model, const Eigen::VectorXd& q, double t,
                      const AnalysisOptions& options);

// At the assembled configuration: each kind's own check of it (a gear pair's centre distance
// against its pitch radii), one warning per constraint that fails it.
void check_assembly(const CompiledModel& model, const Eigen::VectorXd& q,
                    const AnalysisOptions& options);

// The constraints behind a singular Phi_q at the solver's last iterate (the sparse one names
// them only up to kMaxDiagnosedNq coordinates).
std::string singular_diagnosis(const CompiledModel& model, const Solver& solver, const Result&);
std::string singular_diagnosis(const CompiledModel& model, const LargeSolver& solver,
                               const Result& r);

}  // namespace kinegen::codegen::analysis_detail
