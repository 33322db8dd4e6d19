#include "kinegen/codegen/analysis/analysis.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <kinegen/motion.hpp>
#include <kinegen/solver.hpp>
#include <kinegen/sparse_solver.hpp>
#include <limits>
#include <memory>
#include <sstream>

#include "kinegen/codegen/analysis/block_interpreter.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/kinematics.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/model/table.hpp"

namespace kinegen::codegen {

namespace {

// ProgramSystem whose nu can be replaced by a given right-hand side: the solver's velocity
// call at the same (q, t) then solves Phi_q x = rhs with the factorization it already holds,
// which is how sensitivities reuse it without a solver interface of their own.
class RhsSystem : public ProgramSystem {
 public:
  using ProgramSystem::ProgramSystem;
  void nu(const double* q, double t, double* out) const {
    if (rhs_)
      std::copy(rhs_, rhs_ + nc(), out);
    else
      ProgramSystem::nu(q, t, out);
  }
  void use_rhs(const double* rhs) { rhs_ = rhs; }

 private:
  const double* rhs_ = nullptr;
};

using Solver = BasicSolver<RhsSystem>;
using LargeSolver = SparseSolver<RhsSystem>;

// The sparse path names the constraints behind a singular Phi_q (a dense SVD) only up to this
// many coordinates: the diagnosis runs only on failure, but costs O(nq^2) memory and O(nq^3)
// time (JacobiSVD: about 6 s at nq = 600).
constexpr int kMaxDiagnosedNq = 400;

Eigen::MatrixXd jacobian_at(const CompiledModel& model, const Eigen::VectorXd& q, double t) {
  ModelEvaluator<double> eval(model);
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(model.nc(), model.nq());
  eval.jacobian(q.data(), t, jac);
  return jac;
}

}  // namespace

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
  if (!s.allFinite()) return "";
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

namespace {

// The constraints furthest from being satisfied at q, for messages about failed assembly: the
// largest residual and every row within a factor 10 of it.
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

// Rows of Phi_q that depend on earlier rows (file order): adding them does not raise the rank.
std::vector<int> dependent_rows(const Eigen::MatrixXd& scaled, double tol) {
  std::vector<int> dependent;
  Eigen::MatrixXd kept(0, scaled.cols());
  for (int r = 0; r < scaled.rows(); ++r) {
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
  // The bodies that still move with every constraint held, at q0: the coordinates in the null
  // space of Phi_q. They, not the drivers, are where a joint (a ground pivot) or a driver is
  // missing.
  std::vector<int> free_bodies;
  if (nq <= kMaxDiagnosedNq) {
    const Eigen::MatrixXd jac = scaled_jacobian(model, jacobian_at(model, model.q0(), 0.0));
    if (jac.allFinite()) {
      Eigen::JacobiSVD<Eigen::MatrixXd> svd(jac, Eigen::ComputeFullV);
      const auto& sv = svd.singularValues();
      const double tol = 1e-9 * std::max(1.0, sv.size() ? sv[0] : 1.0);
      int rank = 0;
      for (int k = 0; k < sv.size(); ++k) rank += sv[k] > tol;
      const Eigen::MatrixXd kernel = svd.matrixV().rightCols(nq - rank);
      for (std::size_t b = 0; b < m.bodies.size(); ++b)
        if (kernel.middleRows(3 * static_cast<int>(b), 3).cwiseAbs().maxCoeff() > 1e-6)
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

PointState point_state(const Eigen::Vector3d& q, const Eigen::Vector3d& qd,
                       const Eigen::Vector3d& qdd, const Eigen::Vector2d& s) {
  const auto k =
      point_kinematics(q.data(), qd.data(), qdd.data(), std::cos(q[2]), std::sin(q[2]), s[0], s[1]);
  PointState p;
  p.r = {k[0], k[1]};
  p.v = {k[2], k[3]};
  p.a = {k[4], k[5]};
  return p;
}

namespace {

}  // namespace

std::string redundant_constraints(const CompiledModel& model, const Eigen::VectorXd& q, double t) {
  if (model.nc() <= model.nq()) return "";
  const Eigen::MatrixXd scaled = scaled_jacobian(model, jacobian_at(model, q, t));
  std::string names;
  for (int r : dependent_rows(scaled, 1e-9)) names += (names.empty() ? "" : "; ") + model.row_label(r);
  return names;
}

namespace {

// At the assembled configuration: the rank of Phi_q, and the equations that repeat earlier
// ones. Consistent redundancy is solved by least squares with a warning (an error under
// --strict); a rank below nq is left to the solver, which reports it as singular.
void check_redundancy(const CompiledModel& model, const Eigen::VectorXd& q, double t,
                      const AnalysisOptions& options) {
  if (model.nc() <= model.nq()) return;
  const Eigen::MatrixXd scaled = scaled_jacobian(model, jacobian_at(model, q, t));
  const std::vector<int> dependent = dependent_rows(scaled, 1e-9);
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

// Newton's first steps can move an angle by many turns (a driver at t = 2 pi 1e6 moves its
// crank by 1e6 turns in one step, and the coupler's angle follows by some arbitrary amount).
// Where an angle enters only through sin and cos, whole turns are not seen by Phi: bring each
// such angle back into the turn of its estimate q0, so the first row reads as the file meant.
template <class S>
void keep_turns_of_estimates(S& solver, const CompiledModel& model, Eigen::VectorXd& q, double t) {
  const double two_pi = 2 * std::acos(-1.0);
  const Eigen::VectorXd q0 = model.q0();
  const auto& kinds = model.symbolic().coordinate_kinds;
  for (int k = 0; k < q.size(); ++k) {
    if (kinds[k] != CoordinateKind::kAngle) continue;
    const double turns = std::round((q[k] - q0[k]) / two_pi);
    if (turns == 0) continue;
    Eigen::VectorXd trial = q;
    trial[k] -= turns * two_pi;
    const double wanted = trial[k];
    if (solver.position(trial, t) && std::abs(trial[k] - wanted) < 1e-6) q = trial;
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

// dq/dp = -Phi_q^-1 Phi_p at the converged row.q, one column per parameter, through the
// factorization the velocity solve left (same q and t: the solver does not factor again).
template <class S, class Fail>
void solve_sensitivities(S& solver, const SensitivityModel& sensitivity,
                         ProgramEvaluator<double>& phi_p_eval, const CompiledModel& model, double t,
                         StateRow& row, const Fail& fail) {
  const int nc = model.nc(), np = static_cast<int>(sensitivity.params.size());
  Eigen::VectorXd phi_p(static_cast<Eigen::Index>(nc) * np);
  if (np > 0) phi_p_eval.run(row.q.data(), nullptr, t, model.params().data(), phi_p.data());
  phi_p = -phi_p;
  row.dq_dp.resize(model.nq(), np);
  typename S::Vector column(model.nq());
  for (int k = 0; k < np; ++k) {
    solver.system().use_rhs(phi_p.data() + static_cast<Eigen::Index>(k) * nc);
    const Result r = solver.velocity(row.q, t, column);
    solver.system().use_rhs(nullptr);
    if (!r) fail("sensitivity", t, r);
    row.dq_dp.col(k) = column.array() + 0.0;  // -0 (from -Phi_p = -0) prints as 0
  }
}

// The block step as the runtime's Solver reports it (kinegen/block_solver.hpp, to_result).
Result block_result(const BlockInterpreter::Report& report, int nq) {
  Result r;
  r.status = static_cast<Status>(report.status);
  r.iterations = report.iterations;
  r.step = report.step;
  r.block = report.block;
  r.rank = nq;
  r.residual = report.residual;
  r.condition = report.rcond > 0 ? 1 / report.rcond : std::numeric_limits<double>::infinity();
  if (r.status == Status::kSingular) {
    r.pivot_ratio = 0;
    r.rank = nq - 1;
    r.condition = std::numeric_limits<double>::infinity();
  }
  return r;
}

// The time loop, on either solver (dense or sparse Phi_q). With `blocks`, q, qd and qdd come
// from the block program, as a generated kinegen::Solver computes them; the dense or sparse
// solver then only serves the sensitivities and the first solve's turn check.
template <class S>
void analyze(S& solver, const CompiledModel& model, const TimeGrid& grid,
             const std::function<void(const StateRow&)>& sink, const AnalysisOptions& options,
             BlockInterpreter* blocks) {
  const std::string& file = model.mechanism().source;
  const auto& scales = model.symbolic().coordinate_scales;
  const auto inv_scale = [&](int k) { return 1 / scales[k]; };
  std::vector<int> all_coordinates(model.nq());
  for (int k = 0; k < model.nq(); ++k) all_coordinates[k] = k;
  const std::vector<int>& predicted = blocks ? blocks->newton_coordinates() : all_coordinates;
  StateRow row;
  row.q = model.q0();
  row.qd = Eigen::VectorXd::Zero(model.nq());
  row.qdd = Eigen::VectorXd::Zero(model.nq());
  OutputEvaluator outputs(model);
  bool first_solve = true;  // the first position solve starts from the file's q0
  const auto fail = [&](const char* stage, double t, Result r) {
    // Newton that ends near a singular Phi_q (as at a toggle, where it converges only
    // linearly) is reported as singular, as a solved position there is. Newton stalled at a
    // step that vanished, short of the residual: the constraints contradict each other (a
    // redundant model slightly off), whatever the iteration count says.
    if (r.status == Status::kMaxIterations && r.condition > options.max_condition)
      r.status = Status::kSingular;
    if (r.status == Status::kMaxIterations && r.step <= 1e-10) r.status = Status::kInconsistent;
    std::string message = file + ": " + stage + " analysis failed at " + format_time(t) + ": " +
                          r.message();
    if (r.status == Status::kMaxIterations || r.status == Status::kInconsistent) {
      if (r.status == Status::kMaxIterations)
        message += " in " + std::to_string(r.iterations) + " iterations (last scaled step " +
                   format_estimate(r.step) + "); the mechanism may not assemble here";
      message += largest_residual(model, row.q, t) + " (condition estimate of Phi_q " +
                 format_estimate(r.condition) + " at the last iterate)";
    }
    if (r.status == Status::kSingular) {
      if (!blocks)
        message += singular_diagnosis(model, solver, r);
      else if (r.block >= 0) {  // the failed block's rows and columns: q is solved up to it
        const Block& b = blocks->structure().plans[r.block].block;
        if (static_cast<int>(b.cols.size()) <= kMaxDiagnosedNq)
          message += singular_rows(model, jacobian_at(model, row.q, t), b.rows, b.cols);
      } else if (model.nq() <= kMaxDiagnosedNq)
        message += singular_rows(model, jacobian_at(model, row.q, t));
      if (r.block >= 0 && blocks)
        message += "; block " + std::to_string(r.block) + " of the block solver";
      if (std::string(stage) == "position")
        message += "; a toggle or dead-centre position (a driver past what the mechanism can "
                   "reach), or constraints that leave a motion undriven";
    }
    if (first_solve && std::string(stage) == "position") {
      const Eigen::VectorXd& q0 = model.q0();
      message += q0.cwiseAbs().maxCoeff() == 0
                     ? "; every q0 estimate in the file is 0: Newton starts from all bodies on "
                       "top of each other, where Phi_q is singular; give each body's q0 near its "
                       "assembled position"
                     : "; this is the first solve, from the q0 estimates in the file: check "
                       "that they are near an assembled position (a far-off q0 can start "
                       "Newton at a singular or unreachable point)";
    }
    throw AnalysisError(message);
  };
  const SensitivityModel* sensitivity = options.sensitivity;
  std::unique_ptr<ProgramEvaluator<double>> phi_p_eval;
  if (sensitivity) phi_p_eval = std::make_unique<ProgramEvaluator<double>>(sensitivity->phi_p);
  std::unique_ptr<ForceSolver> force_solver;
  if (options.forces) force_solver = std::make_unique<ForceSolver>(model, *options.forces);
  bool force_warned = false;
  // kinegen::Solver's defaults in double (default_options, as Solver::block_options copies them).
  BlockInterpreter::Options block_options;
  {
    const SolverOptions s = default_options<double>();
    block_options.tolerance = s.tolerance;
    block_options.max_iterations = s.max_iterations;
    block_options.fixed_iterations = s.fixed_iterations;
    block_options.singular_pivot_ratio = s.singular_pivot_ratio;
    block_options.min_rcond = s.min_rcond;
    block_options.residual_tolerance = s.residual_tolerance;
  }
  StateRow previous;
  Eigen::VectorXd qdd_before;  // the acceleration one step before `previous` (the jerk)
  double h_before = 0;
  int previous_sign = 0;
  for (int k = 0; k <= grid.steps; ++k) {
    const double t = grid.at(k);
    if (k > 0) {
      // The runtime's predictor from the last solved state keeps Newton on its branch.
      const double h = t - row.t;
      const TaylorPredictor<double> predict(h, h_before, k > 1);
      // The block path predicts what Solver::step predicts, the coordinates Newton iterates:
      // the others are assigned, and their start value sets how their sin and cos rotate.
      for (int c : predicted)
        row.q[c] = predict(row.q[c], row.qd[c], row.qdd[c], k > 1 ? qdd_before[c] : 0.0);
    }
    row.t = t;
    if (const std::string table = table_outside(model.mechanism(), t); !table.empty())
      throw AnalysisError(file + ": position analysis failed at " + format_time(t) +
                          ": t lies outside " + table);
    if (blocks) {
      // Solver::step's solve: the first one iterates to convergence whatever the options.
      BlockInterpreter::Options o = block_options;
      if (k == 0) o.fixed_iterations = 0;
      // A solve that fails, or succeeds near a toggle (Newton converging onto it), ends the
      // analysis; a failed position may be retried once from the last solution.
      const auto solve = [&](bool may_retry) {
        Result r = block_result(
            blocks->solve_step(row.q.data(), t, row.qd.data(), row.qdd.data(), o), model.nq());
        if (!r && may_retry && blocks->failed_phase() == BlockInterpreter::Phase::kPosition)
          return false;
        if (!r) fail(BlockInterpreter::to_string(blocks->failed_phase()), t, r);
        if (r.condition > options.max_condition) {
          r.status = Status::kSingular;
          fail("position", t, r);
        }
        return true;
      };
      if (!solve(k > 0)) {
        row.q = previous.q;
        solve(false);
      }
      first_solve = false;
      if (k == 0) {
        // As on the dense path, but a changed estimate is solved again from scratch (then
        // analyze and a Solver started from the file's q0 differ by whole turns).
        const Eigen::VectorXd before = row.q;
        keep_turns_of_estimates(solver, model, row.q, t);
        if (row.q != before) {
          blocks->reset();
          solve(false);
        }
        check_redundancy(model, row.q, t, options);
        check_assembly(model, row.q, options);
      }
    } else {
      if (auto r = solver.position(row.q, t); !r) {
        // A coarse step can predict a point from which Newton cannot find its way; start once
        // more from the last solution before giving up (the jump check below still applies).
        if (k == 0) fail("position", t, r);
        row.q = previous.q;
        if (auto r2 = solver.position(row.q, t); !r2) fail("position", t, r2);
      }
      first_solve = false;
      if (k == 0) {
        keep_turns_of_estimates(solver, model, row.q, t);
        check_redundancy(model, row.q, t, options);
        check_assembly(model, row.q, options);
      }
      if (auto r = solver.velocity(row.q, t, row.qd); !r) {
        fail("velocity", t, r);
      } else if (r.condition > options.max_condition) {
        // Newton converges (slowly) onto a toggle point, where Phi_q is singular only in the
        // limit: velocities there are meaningless, so it counts as singular.
        r.status = Status::kSingular;
        fail("position", t, r);
      }
      if (auto r = solver.acceleration(row.q, row.qd, t, row.qdd); !r) fail("acceleration", t, r);
    }
    if (sensitivity) solve_sensitivities(solver, *sensitivity, *phi_p_eval, model, t, row, fail);
    if (k > 0 && options.check_jumps) {
      // The runtime's test (kinegen/motion.hpp), the one Solver::step applies.
      const MotionCheck motion = check_motion(
          predicted, t - previous.t, previous.q, previous.qd, previous.qdd, row.q, row.qd,
          row.qdd, inv_scale, options.jump_fraction, std::numeric_limits<double>::epsilon());
      if (motion.jumped())
        throw AnalysisError(
            file + ": position analysis failed at " + format_time(t) +
            ": the solution jumped (scaled change " + format_number(motion.change) + " since " +
            format_time(previous.t) + " disagrees with the velocities by " +
            format_number(motion.miss) +
            "): Newton left the assembly branch it started on, or the step is too coarse to tell; "
            "use smaller steps (--steps)");
      const int sign = blocks ? 0 : solver.jacobian_sign();
      if (previous_sign != 0 && sign != 0 && sign != previous_sign)
        throw AnalysisError(file + ": position analysis failed at " + format_time(t) +
                            ": det(Phi_q) changed sign since " + format_time(previous.t) +
                            ": the solution crossed a singular configuration or jumped to "
                            "another assembly branch; use smaller steps (--steps)");
    }
    if (!blocks) previous_sign = solver.jacobian_sign();
    row.points.clear();
    const auto& points = model.mechanism().points;
    for (std::size_t p = 0; p < points.size(); ++p) {
      const int b = 3 * points[p].body;
      row.points.push_back(point_state(row.q.segment<3>(b), row.qd.segment<3>(b),
                                       row.qdd.segment<3>(b), model.point_offsets()[p]));
    }
    outputs.evaluate(t, row.q, row.qd, row.qdd, row.outputs);
    if (sensitivity) {
      point_sensitivities(model, *sensitivity, row.q, row.dq_dp, row.dpoints_dp);
      output_sensitivities(model, *sensitivity, t, row.q, row.dq_dp, row.doutputs_dp);
    }
    if (force_solver) {
      if (!force_solver->solve(t, row.q, row.qd, row.qdd, row.forces))
        throw AnalysisError(file + ": force analysis failed at " + format_time(t) +
                            ": Phi_q is singular (scaled condition estimate " +
                            format_estimate(force_solver->condition()) + ", the limit " +
                            format_estimate(1 / force_min_rcond<double>()) +
                            "), so no finite efforts hold the motion (a toggle or dead-centre "
                            "position)");
      if (!force_warned && force_solver->condition() > options.force_warning && options.warn) {
        options.warn(file + ": at " + format_time(t) + " the scaled condition estimate of Phi_q is " +
                     format_estimate(force_solver->condition()) + " (above " +
                     format_estimate(options.force_warning) +
                     "): the mechanism nears a toggle, where efforts and reactions grow without "
                     "bound");
        force_warned = true;
      }
    }
    sink(row);
    if (k > 0) {
      qdd_before = previous.qdd;
      h_before = t - previous.t;
    }
    previous = row;
  }
}

}  // namespace

void run_analysis(const CompiledModel& model, const TimeGrid& grid,
                  const std::function<void(const StateRow&)>& sink) {
  run_analysis(model, grid, sink, AnalysisOptions{});
}

void run_analysis(const CompiledModel& model, const TimeGrid& grid,
                  const std::function<void(const StateRow&)>& sink,
                  const AnalysisOptions& options) {
  require_driven(model);
  std::unique_ptr<BlockInterpreter> blocks;
  if (options.block_solver && model.nq() == model.nc() &&
      BlockInterpreter::supported(model.structure()))
    blocks = std::make_unique<BlockInterpreter>(model);
  if (model.nq() == model.nc() && model.nq() > options.sparse_above_nq) {
    LargeSolver solver{RhsSystem(model)};
    analyze(solver, model, grid, sink, options, blocks.get());
  } else {
    Solver solver{RhsSystem(model)};
    analyze(solver, model, grid, sink, options, blocks.get());
  }
}

OutputEvaluator::OutputEvaluator(const CompiledModel& model)
    : nq_(model.nq()),
      n_(model.programs().num_outputs),
      params_(model.params()),
      values_(n_),
      rates_(static_cast<std::size_t>(n_) * (2 + nq_)),
      value_program_(model.programs().outputs),
      rate_program_(model.programs().output_rates) {}

void OutputEvaluator::evaluate(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                               const Eigen::VectorXd& qdd,
                               std::vector<std::array<double, 3>>& out) {
  out.resize(n_);
  if (n_ == 0) return;
  value_program_.run(q.data(), nullptr, t, params_.data(), values_.data());
  rate_program_.run(q.data(), qd.data(), t, params_.data(), rates_.data());
  for (int o = 0; o < n_; ++o) {
    double a = rates_[n_ + o];
    const double* grad = &rates_[2 * n_ + static_cast<std::size_t>(o) * nq_];
    for (int k = 0; k < nq_; ++k) a += grad[k] * qdd[k];
    out[o] = {values_[o], rates_[o], a};
  }
}

std::string csv_header(const Mechanism& m) {
  std::string h = "t";
  for (const auto& b : m.bodies)
    for (const char* c : {"x", "y", "phi", "vx", "vy", "omega", "ax", "ay", "alpha"})
      h += "," + b.name + "." + c;
  for (const auto& q : m.coordinates) h += "," + q.name + "," + q.name + ".v," + q.name + ".a";
  for (const auto& p : m.points)
    for (const char* c : {"x", "y", "vx", "vy", "ax", "ay"}) h += "," + p.name + "." + c;
  for (const auto& o : m.outputs) h += "," + o.name + "," + o.name + ".v," + o.name + ".a";
  return h + "\n";
}

std::string csv_header(const Mechanism& m, const std::vector<std::string>& sensitivity) {
  return csv_header(m, {}, sensitivity);
}

std::string csv_header(const Mechanism& m, const std::vector<std::string>& forces,
                       const std::vector<std::string>& sensitivity) {
  std::string h = csv_header(m);
  h.pop_back();  // the line break
  for (const auto& c : forces) h += "," + c;
  for (const auto& c : sensitivity_columns(m, sensitivity)) h += "," + c;
  return h + "\n";
}

std::string csv_row(const StateRow& row, int num_bodies) {
  std::string s = format_number(row.t);
  for (int b = 0; b < num_bodies; ++b) {
    for (int c = 0; c < 3; ++c) s += "," + format_number(row.q[3 * b + c]);
    for (int c = 0; c < 3; ++c) s += "," + format_number(row.qd[3 * b + c]);
    for (int c = 0; c < 3; ++c) s += "," + format_number(row.qdd[3 * b + c]);
  }
  for (int k = 3 * num_bodies; k < row.q.size(); ++k)  // extra coordinates (format 6.1)
    s += "," + format_number(row.q[k]) + "," + format_number(row.qd[k]) + "," +
         format_number(row.qdd[k]);
  for (const auto& p : row.points)
    for (const Eigen::Vector2d* v : {&p.r, &p.v, &p.a})
      s += "," + format_number((*v)[0]) + "," + format_number((*v)[1]);
  for (const auto& o : row.outputs)
    for (double v : o) s += "," + format_number(v);
  for (double f : row.forces) s += "," + format_number(f);
  // Sensitivities: per parameter, every coordinate (the bodies' x, y, phi, the extra ones),
  // the points' x, y, the outputs (6.6), as sensitivity_columns names them.
  for (int k = 0; k < row.dq_dp.cols(); ++k) {
    for (int i = 0; i < row.dq_dp.rows(); ++i) s += "," + format_number(row.dq_dp(i, k));
    for (int i = 0; i < row.dpoints_dp.rows(); ++i) s += "," + format_number(row.dpoints_dp(i, k));
    for (int i = 0; i < row.doutputs_dp.rows(); ++i)
      s += "," + format_number(row.doutputs_dp(i, k));
  }
  return s + "\n";
}

}  // namespace kinegen::codegen
