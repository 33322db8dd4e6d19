// The analysis' checks and diagnoses: whether the mechanism is driven, redundant constraints,
// each type's assembly check, and the messages that name the constraints behind a singular or
// unsatisfied Phi_q.
#include "diagnosis.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

namespace {

std::vector<int> dependent_rows(const Eigen::MatrixXd& scaled, double tol, int tail_first) {
  std::vector<int> dependent, order;
  // A spatial file's normalization rows (the last ones) come first: they are the tool's own,
  // and the dependent row to name is one of the file's joints or drivers.
  for (int r = static_cast<int>(scaled.rows()) - tail_first; r < scaled.rows(); ++r)
    order.push_back(r);
  for (int r = 0; r < scaled.rows() - tail_first; ++r) order.push_back(r);
  Eigen::MatrixXd kept(0, scaled.cols());
  for (int r : order) {
    Eigen::MatrixXd trial(kept.rows() + 1, scaled.cols());
    trial << kept, scaled.row(r);
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(trial.transpose());
    qr.setThreshold(tol);
    if (qr.rank() == trial.rows())
      kept = trial;
    else
      dependent.push_back(r);
  }
  return dependent;
}

}  // namespace

namespace analysis_detail {

Eigen::MatrixXd jacobian_at(const CompiledModel& model, const Eigen::VectorXd& q, double t) {
  ModelEvaluator<double> eval(model);
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(model.nc(), model.nq());
  eval.jacobian(q.data(), t, jac);
  return jac;
}

// The constraints behind a (near-)singular Phi_q: rows that carry weight in the left singular
// vectors of its smallest singular values (those within a factor 10 of the smallest, and
// always the smallest), with the scaled condition estimate. rows and cols: the submatrix to
// look at (a failed block's: its rows depend on its own and earlier blocks' coordinates only,
// so later blocks' unsolved values do not enter), or empty for all of Phi_q.
std::string singular_rows(const CompiledModel& model, const Eigen::MatrixXd& jac,
                          std::vector<int> rows, std::vector<int> cols) {
  if (rows.empty())
    for (int r = 0; r < jac.rows(); ++r) rows.push_back(r);
  if (cols.empty())
    for (int c = 0; c < jac.cols(); ++c) cols.push_back(c);
  // Rows equilibrated over all of Phi_q (couplings to earlier blocks included, as the block
  // solver's condition estimate measures a block).
  const Eigen::MatrixXd full = scaled_jacobian(model, jac);
  Eigen::MatrixXd s(rows.size(), cols.size());
  for (std::size_t i = 0; i < rows.size(); ++i)
    for (std::size_t j = 0; j < cols.size(); ++j) s(i, j) = full(rows[i], cols[j]);
  // Eigen's SVD reads the first entry even of an empty matrix.
  if (!s.allFinite() || s.size() == 0) return "";
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(s, Eigen::ComputeFullU);
  const Eigen::VectorXd sv = svd.singularValues();
  const double s_max = sv.size() ? sv(0) : 0.0;
  // With nc > nq the last nc - nq left singular vectors span the redundancy, not the
  // singularity: look at the nq-th singular value.
  const int k_min = static_cast<int>(std::min(s.rows(), s.cols())) - 1;
  const double s_min = k_min >= 0 ? sv(k_min) : 0.0;
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(s.rows());
  for (int k = 0; k <= k_min; ++k)
    if (k == k_min || sv(k) <= 10 * s_min + 1e-14 * s_max)
      weight = weight.cwiseMax(svd.matrixU().col(k).cwiseAbs());
  std::string names;
  for (int r = 0; r < weight.size(); ++r)
    if (weight[r] > 0.1) names += (names.empty() ? "" : "; ") + model.row_label(rows[r]);
  std::ostringstream os;
  os << " (condition estimate " << (s_min > 0 ? format_estimate(s_max / s_min) : "inf")
     << "; involved: " << names << ")";
  return os.str();
}

// The constraints furthest from being satisfied at q, for messages about failed assembly: the

std::string largest_residual(const CompiledModel& model, const Eigen::VectorXd& q, double t) {
  ModelEvaluator<double> eval(model);
  Eigen::VectorXd phi(model.nc());
  eval.phi(q.data(), t, phi.data());
  Eigen::Index row = 0;
  const double largest = phi.cwiseAbs().maxCoeff(&row);
  std::string others;
  for (int r = 0; r < phi.size(); ++r)
    if (r != row && std::abs(phi[r]) > 0.1 * largest)
      others += "; " + format_number(phi[r]) + " in " + model.row_label(r);
  return "; largest residual " + format_number(phi[row]) + " in " +
         model.row_label(static_cast<int>(row)) + others;
}

std::string nonfinite_rows(const CompiledModel& model, const Eigen::VectorXd& q,
                           const Eigen::VectorXd& qd, double t) {
  ModelEvaluator<double> eval(model);
  const int nc = model.nc();
  Eigen::VectorXd phi(nc), nu(nc), gamma(nc);
  eval.phi(q.data(), t, phi.data());
  const Eigen::MatrixXd jac = jacobian_at(model, q, t);
  eval.nu(q.data(), t, nu.data());
  eval.gamma(q.data(), qd.data(), t, gamma.data());
  std::string found;
  for (int r = 0; r < nc && found.empty(); ++r) {
    const char* what = !std::isfinite(phi[r])     ? "Phi"
                       : !jac.row(r).allFinite()  ? "Phi_q"
                       : !std::isfinite(nu[r])    ? "nu (the velocity's right-hand side)"
                       : !std::isfinite(gamma[r]) ? "gamma (the acceleration's right-hand side)"
                                                  : nullptr;
    if (what) found = std::string(what) + " of " + model.row_label(r);
  }
  if (found.empty()) return "";
  return "; not finite at " + format_time(t) + ": " + found +
         " (a driver's law, a table, a curve or a parameter beyond a double there)";
}

// At the assembled configuration: the rank of Phi_q, and the equations that repeat earlier
// ones. Consistent redundancy is solved by least squares with a warning (an error under
// --strict); a rank below nq is left to the solver, which reports it as singular.
void check_redundancy(const CompiledModel& model, const Eigen::VectorXd& q, double t,
                      const AnalysisOptions& options) {
  if (model.nc() <= model.nq()) return;
  const Eigen::MatrixXd scaled = scaled_jacobian(model, jacobian_at(model, q, t));
  const std::vector<int> dependent =
      dependent_rows(scaled, 1e-9, static_cast<int>(model.mechanism().normalization.size()));
  if (dependent.empty()) return;
  std::string names;
  for (int r : dependent) names += (names.empty() ? "" : "; ") + model.row_label(r);
  const int rank = model.nc() - static_cast<int>(dependent.size());
  const std::string what = std::to_string(model.nc()) + " equations for " +
                           std::to_string(model.nq()) + " coordinates, rank " +
                           std::to_string(rank) + " at " + format_time(t) + ": redundant: " + names;
  const std::string& file = model.mechanism().source;
  if (options.strict)
    throw InputError(file, "joints", {},
                     "redundant constraints (" + what + "); --strict rejects them: remove them");
  if (options.warn)
    options.warn(file + ": redundant constraints (" + what +
                 "); solving the consistent system by least squares");
}

// At the assembled configuration: each kind's own check of it (a gear pair's centre distance
// against its pitch radii), one warning per constraint that fails it.
void check_assembly(const CompiledModel& model, const Eigen::VectorXd& q,
                    const AnalysisOptions& options) {
  if (!options.warn) return;
  const std::string& file = model.mechanism().source;
  for (const Constraint* c : model.mechanism().constraints()) {
    if (!c->kind->assembly_warning) continue;
    const DrawContext context{*c, [&](const Expr& e) { return model.geometry_number(e, c->item); }};
    const std::string message = c->kind->assembly_warning(context, q);
    if (message.empty()) continue;
    const std::string line = c->loc.line > 0 ? ":" + std::to_string(c->loc.line) : "";
    options.warn(file + line + ": " + c->item + ": " + message);
  }
}

std::string singular_diagnosis(const CompiledModel& model, const Solver& solver, const Result&) {
  return singular_rows(model, solver.jacobian());
}

std::string singular_diagnosis(const CompiledModel& model, const LargeSolver& solver,
                               const Result& r) {
  if (model.nq() <= kMaxDiagnosedNq)
    return singular_rows(model, Eigen::MatrixXd(solver.jacobian()));
  return " (condition estimate " + format_estimate(r.condition) + "; " +
         std::to_string(model.nq()) + " coordinates are too many to name the constraints " +
         "involved, at most " + std::to_string(kMaxDiagnosedNq) + ")";
}

}  // namespace analysis_detail

using namespace analysis_detail;

Eigen::MatrixXd scaled_jacobian(const CompiledModel& model, const Eigen::MatrixXd& jac,
                                Eigen::VectorXd* row_scale) {
  Eigen::MatrixXd s = jac;
  for (int k = 0; k < s.cols(); ++k) s.col(k) *= model.symbolic().coordinate_scales[k];
  if (row_scale) row_scale->resize(s.rows());
  for (int r = 0; r < s.rows(); ++r) {
    const double n = s.row(r).cwiseAbs().maxCoeff();
    const double scale = n > 0 ? 1 / n : 1;
    s.row(r) *= scale;
    if (row_scale) (*row_scale)[r] = scale;
  }
  return s;
}

void require_driven(const CompiledModel& model) {
  const int nq = model.nq(), nc = model.nc();
  const Mechanism& m = model.mechanism();
  // More equations than coordinates is allowed: run_analysis checks at the assembled position
  // whether they are consistent and redundant (solved by least squares, with a warning) or not.
  if (nc >= nq) return;
  std::string what = "the mechanism is not kinematically driven: " + std::to_string(nc) +
                     " equations for " + std::to_string(nq) + " coordinates leave " +
                     std::to_string(nq - nc) + " degree(s) of freedom undriven";
  if (m.spatial) {  // the normalization rows are the tool's own, not joints (Gruebler)
    int joint_rows = 0;
    for (const Constraint& c : m.joints) joint_rows += c.equation_count();
    what += " (the Euler parameter rows included; Gruebler counts 6 x " +
            std::to_string(m.bodies.size()) + " - " + std::to_string(joint_rows) + " = " +
            std::to_string(6 * static_cast<int>(m.bodies.size()) - joint_rows) +
            " before the drivers)";
  }
  // The bodies that still move with every constraint held, at q0: the coordinates in the null
  // space of Phi_q. They, not the drivers, are where a joint (a ground pivot) or a driver is
  // missing.
  std::vector<int> free_bodies;
  if (nq <= kMaxDiagnosedNq) {
    const Eigen::MatrixXd jac = scaled_jacobian(model, jacobian_at(model, model.q0(), 0.0));
    if (jac.allFinite()) {
      // No equations at all: every coordinate is free. (Eigen's SVD of a 0 x nq matrix reads
      // its first entry: the fuzzer's find, a crash of `analyze` on a file with bodies only.)
      Eigen::MatrixXd kernel = Eigen::MatrixXd::Identity(nq, nq);
      if (nc > 0) {
        Eigen::JacobiSVD<Eigen::MatrixXd> svd(jac, Eigen::ComputeFullV);
        const auto& sv = svd.singularValues();
        const double tol = 1e-9 * std::max(1.0, sv.size() ? sv[0] : 1.0);
        int rank = 0;
        for (int k = 0; k < sv.size(); ++k) rank += sv[k] > tol;
        kernel = svd.matrixV().rightCols(nq - rank);
      }
      for (std::size_t b = 0; b < m.bodies.size(); ++b)
        if (kernel.middleRows(m.body_coordinates() * static_cast<int>(b), m.body_coordinates())
                .cwiseAbs()
                .maxCoeff() > 1e-6)
          free_bodies.push_back(static_cast<int>(b));
    }
  }
  if (free_bodies.empty() || free_bodies.size() > 16)
    throw InputError(m.source, "drivers", {}, what);
  std::string names;
  for (int b : free_bodies) names += (names.empty() ? "'" : ", '") + m.bodies[b].name + "'";
  what += "; " + std::string(free_bodies.size() == 1 ? "body " : "bodies ") + names +
          " can move with every joint and driver held (at q0): a joint (a pivot to ground?) or "
          "a driver is missing";
  // Every body free: most likely a missing driver. Some: the free ones are the place to look.
  if (free_bodies.size() == m.bodies.size()) throw InputError(m.source, "drivers", {}, what);
  throw InputError(m.source, (free_bodies.size() == 1 ? "body " : "bodies ") + names,
                   m.bodies[free_bodies[0]].loc, what);
}

void require_kept_rows(const std::string& what, long long rows, std::size_t per_row,
                       const std::string& option) {
  const std::size_t per = std::max<std::size_t>(per_row, 1);
  if (rows <= 0 || static_cast<unsigned long long>(rows) <= kMaxKeptValues / per) return;
  const bool steps = option == "--steps";  // N steps are N + 1 rows
  const long long fits = static_cast<long long>(kMaxKeptValues / per) - (steps ? 1 : 0);
  throw UsageError(what + " keeps its rows in memory, at most " + std::to_string(kMaxKeptValues) +
                   " numbers: " + std::to_string(rows) + " rows of " + std::to_string(per) +
                   " are more; " + option + " " + std::to_string(fits) +
                   " is the most that fits here" +
                   (steps ? " (kinegen analyze streams its rows to a file instead)" : ""));
}

std::string redundant_constraints(const CompiledModel& model, const Eigen::VectorXd& q, double t) {
  if (model.nc() <= model.nq()) return "";
  const Eigen::MatrixXd scaled = scaled_jacobian(model, jacobian_at(model, q, t));
  std::string names;
  for (int r : dependent_rows(scaled, 1e-9,
                              static_cast<int>(model.mechanism().normalization.size())))
    names += (names.empty() ? "" : "; ") + model.row_label(r);
  return names;
}

}  // namespace kinegen::codegen
