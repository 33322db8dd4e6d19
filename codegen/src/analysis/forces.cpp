// Kinetostatics, the numeric half: the inertia forces and lambda (see forces.hpp); Q^A comes
// from symbolic/forces.cpp.
#include "kinegen/codegen/analysis/forces.hpp"

#include <cmath>
#include <limits>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/base/format.hpp"

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
      programs_(model.force_programs(forces)),
      applied_(programs_->applied),
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

namespace {

// Q^A of `spec` alone at (q, qd, t), or empty when it is all finite.
Eigen::VectorXd applied_of(const CompiledModel& model, const ForceSpec& spec, double t,
                           const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  const ForcePrograms part = compile_forces(derive_forces(model, spec), model.symbols(),
                                            model.symbolic(), model.build_options().fold_params);
  ProgramEvaluator<double> eval(part.applied);
  Eigen::VectorXd out(model.nq());
  eval.run(q.data(), qd.data(), t, model.params().data(), out.data());
  return out;
}

// The first value of v that is not finite, with the coordinate it acts on.
std::string first_nonfinite(const CompiledModel& model, const Eigen::VectorXd& v) {
  const auto labels = coordinate_labels(model.mechanism());
  for (Eigen::Index k = 0; k < v.size(); ++k)
    if (!std::isfinite(v[k]))
      return format_number(v[k]) + " in the generalized force on " + labels[k];
  return "";
}

}  // namespace

std::string ForceSolver::failure_cause(double t, const Eigen::VectorXd& q,
                                       const Eigen::VectorXd& qd,
                                       const Eigen::VectorXd& qdd) const {
  const Mechanism& m = model_->mechanism();
  const ForceSpec& spec = m.forces;
  const auto line = [](const SourceLoc& loc) {
    return loc.line > 0 ? " (line " + std::to_string(loc.line) + ")" : std::string();
  };
  for (const Load& load : spec.loads) {
    ForceSpec one;
    one.loads = {load};
    const std::string value = first_nonfinite(*model_, applied_of(*model_, one, t, q, qd));
    if (!value.empty())
      return "the load " + load.item + line(load.loc) + " is not finite here: " + value;
  }
  const int nb = static_cast<int>(m.bodies.size());
  for (int b = 0; b < nb; ++b) {
    ForceSpec weight;  // this body's mass data and the gravity, nothing else
    weight.bodies.resize(m.bodies.size());
    if (b < static_cast<int>(spec.bodies.size())) weight.bodies[b] = spec.bodies[b];
    weight.gravity = spec.gravity;
    const std::string what = "body '" + m.bodies[b].name + "' (mass " +
                             format_number(forces_->numbers.mass[b]) + ", inertia " +
                             format_number(forces_->numbers.inertia[b]) + ")";
    std::string value = first_nonfinite(*model_, applied_of(*model_, weight, t, q, qd));
    if (!value.empty()) return "the weight of " + what + " overflows: " + value;
    ForceData<double> alone = forces_->numbers;
    for (int k = 0; k < nb; ++k)
      if (k != b) alone.mass[k] = alone.inertia[k] = 0;
    Eigen::VectorXd inertia = Eigen::VectorXd::Zero(model_->nq());
    add_inertia_forces(alone, nb, q.data(), qd.data(), qdd.data(), inertia.data());
    value = first_nonfinite(*model_, inertia);
    if (!value.empty()) return "the inertia force of " + what + " overflows: " + value;
  }
  if (!q_total_.allFinite())
    return "the generalized force overflows: " + first_nonfinite(*model_, q_total_);
  return "the efforts and reactions overflow a double (largest |Q| " +
         format_number(q_total_.cwiseAbs().maxCoeff()) + ", scaled condition estimate " +
         format_estimate(condition_) + ")";
}

}  // namespace kinegen::codegen
