// Kinetostatics, the numeric half: the inertia forces and lambda (see forces.hpp); Q^A comes
// from symbolic/forces.cpp.
#include "kinegen/codegen/analysis/forces.hpp"

#include <cmath>
#include <limits>

#include "kinegen/codegen/analysis/analysis.hpp"

namespace kinegen::codegen {

ForceModel derive_forces(const CompiledModel& model, const ForceSpec& spec) {
  return derive_forces(model.mechanism(), model.symbols(), model.symbolic(), spec);
}

ForceModel forces_for_analysis(const CompiledModel& model, double t0) {
  if (model.nc() != model.nq()) {
    // Name the redundant equations where the analysis would assemble (at t0): solve that one
    // position, quietly; if even that fails, the message says so instead.
    std::string names;
    try {
      Eigen::VectorXd q;
      run_analysis(model, {t0, t0, 0}, [&](const StateRow& row) { q = row.q; });
      if (q.size()) names = redundant_constraints(model, q, t0);
    } catch (const AnalysisError&) {
      names = "";
    }
    throw UsageError(
        "--forces needs as many independent equations as coordinates (" +
        std::to_string(model.nc()) + " equations, " + std::to_string(model.nq()) +
        " coordinates): the reactions of redundant constraints are not unique; " +
        (names.empty() ? std::string("remove the redundant joints")
                       : "remove the redundant equations (at " + format_time(t0) +
                             "): " + names));
  }
  return derive_forces(model);
}

ForceSolver::ForceSolver(const CompiledModel& model, const ForceModel& forces, double min_rcond)
    : model_(&model),
      forces_(&forces),
      eval_(model),
      applied_program_(lower(forces.applied, model.symbols())),
      applied_(applied_program_),
      params_(model.params()),
      jac_(model.nc(), model.nq()),
      q_total_(model.nq()),
      lambda_(model.nc()),
      jac_row_major_(model.nc() * model.nq()),
      lambda_values_(model.nc()),
      min_rcond_(min_rcond) {}

Eigen::VectorXd ForceSolver::reaction_of(int c) const {
  const int r0 = forces_->row_begin[c], n = forces_->row_begin[c + 1] - r0;
  return -jac_.middleRows(r0, n).transpose() * lambda_.segment(r0, n);
}

bool ForceSolver::solve(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                        const Eigen::VectorXd& qdd, std::vector<double>& columns) {
  const Mechanism& m = model_->mechanism();
  jac_.setZero();
  eval_.jacobian(q.data(), t, jac_);
  applied_.run(q.data(), qd.data(), t, params_.data(), q_total_.data());
  add_inertia_forces(forces_->numbers, static_cast<int>(m.bodies.size()), q.data(), qd.data(),
                     qdd.data(), q_total_.data());
  // Phi_q^T lambda = Q, factored scaled like the position solve (rows equilibrated, columns
  // in units of their coordinate's scale) so that the condition estimate means the same.
  const auto& scales = model_->symbolic().coordinate_scales;
  Eigen::VectorXd row_scale;
  const Eigen::MatrixXd scaled = scaled_jacobian(*model_, jac_, &row_scale);
  // scaled = R J C; J^T lambda = Q  <=>  scaled^T (R^-1 lambda) = C Q.
  Eigen::VectorXd rhs = q_total_;
  for (int k = 0; k < rhs.size(); ++k) rhs[k] *= scales[k];
  const Eigen::PartialPivLU<Eigen::MatrixXd> lu(scaled.transpose());
  const double rcond = lu.rcond();
  condition_ = rcond > 0 ? 1 / rcond : std::numeric_limits<double>::infinity();
  lambda_ = lu.solve(rhs);
  for (int r = 0; r < lambda_.size(); ++r) lambda_[r] *= row_scale[r];
  if (!(rcond > min_rcond_) || !lambda_.allFinite()) {
    columns.assign(force_columns(m).size(), std::numeric_limits<double>::quiet_NaN());
    return false;
  }
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      jac_row_major_.data(), jac_.rows(), jac_.cols()) = jac_;
  Eigen::VectorXd::Map(lambda_values_.data(), lambda_.size()) = lambda_;
  columns_from_lambda(m, *forces_, forces_->numbers, q.data(), jac_row_major_, lambda_values_,
                      columns);
  return true;
}

}  // namespace kinegen::codegen
