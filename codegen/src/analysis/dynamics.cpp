// Forward dynamics in minimal coordinates, in-process (see analysis/dynamics.hpp).
#include "kinegen/codegen/analysis/dynamics.hpp"

#include <Eigen/SparseLU>
#include <cmath>
#include <kinegen/block_options.hpp>
#include <kinegen/kernels/dynamics.hpp>
#include <kinegen/solver.hpp>
#include <limits>
#include <optional>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/block_interpreter.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "diagnosis.hpp"

namespace kinegen::codegen {

namespace {

// The continuation steps of a first solve from the free items' values at_q to z: each item's
// change against 0.25 rad (an angle) or 0.1 length scales (a length, a distance), its kind read
// as the generated header reads it (the first coordinate of the item's row, as free_scale).
int continuation_steps(const CompiledModel& model, const std::vector<int>& free_rows,
                       const Eigen::VectorXd& at_q, const Eigen::VectorXd& z) {
  const Mechanism& m = model.mechanism();
  const std::vector<int> free = m.free_drivers();
  const auto& rows = model.programs().jac_rows;
  const auto& cols = model.programs().jac_cols;
  const auto& kinds = model.symbolic().coordinate_kinds;
  constexpr int kMax = kernels::ReportKernel::_kMaxContinuationSteps;
  double need = 0;
  for (std::size_t k = 0; k < free_rows.size(); ++k) {
    int column = 0;
    for (std::size_t e = 0; e < rows.size(); ++e) {
      if (rows[e] == free_rows[k]) {
        column = cols[e];
        break;
      }
    }
    const bool angle = !is_distance(m.drivers[free[k]]) && kinds[column] == CoordinateKind::kAngle;
    const double limit = angle ? 0.25 : 0.1 * model.symbolic().length_scale;
    const double n = std::abs(z[k] - at_q[k]) / limit;
    if (!(n <= need)) need = n;
  }
  if (!(need <= kMax)) return kMax + 1;
  return need > 1 ? static_cast<int>(std::ceil(need)) : 1;
}

using K = kernels::DynamicsKernel;
using analysis_detail::singular_rows;

// Where the integrator gives up and Phi_q's condition estimate has grown this much since t0,
// the cause is the singular position it approaches (singular_diagnosis).
constexpr double kNearSingular = 1e3;

BlockInterpreter::Options block_options() {
  return block_options_from<BlockInterpreter::Options>(default_options<double>());
}

// The numerical rank of the rows `rows` of the scaled Phi_q.
int rank_of(const Eigen::MatrixXd& scaled, const std::vector<int>& rows) {
  if (rows.empty()) return 0;
  Eigen::MatrixXd s(rows.size(), scaled.cols());
  for (std::size_t i = 0; i < rows.size(); ++i) s.row(i) = scaled.row(rows[i]);
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(s);
  qr.setThreshold(1e-10);
  return static_cast<int>(qr.rank());
}

}  // namespace

std::vector<std::string> free_names(const Mechanism& m) {
  std::vector<std::string> names;
  for (int d : m.free_drivers()) names.push_back(m.drivers[d].name);
  return names;
}

struct ReducedDynamics::Impl {
  explicit Impl(const CompiledModel& model, const ForceModel& forces)
      : eval(model),
        programs(model.force_programs(forces)),
        applied(programs->applied),
        nonconservative(programs->nonconservative),
        potential(programs->potential),
        free_values(model.free_programs().values),
        inputs(model.mechanism().input_slots(), 0.0) {
    eval.set_inputs(inputs.data());
    applied.set_inputs(inputs.data());
    nonconservative.set_inputs(inputs.data());
    if (model.nq() == model.nc() && BlockInterpreter::supported(model.structure())) {
      blocks = std::make_unique<BlockInterpreter>(model);
      blocks->set_inputs(inputs.data());
    } else {
      dense.emplace(ProgramSystem(model));
      dense->system().set_inputs(inputs.data());
    }
  }

  ModelEvaluator<double> eval;
  std::shared_ptr<const ForcePrograms> programs;  // the compile stage's
  ProgramEvaluator<double> applied;
  ProgramEvaluator<double> nonconservative;
  ProgramEvaluator<double> potential;
  ProgramEvaluator<double> free_values;
  // 3 per driver (the free items' z, zd and 0 (zdd); an input driver's value, rate and
  // acceleration), then the loads' inputs (Mechanism::input_slots).
  std::vector<double> inputs;
  std::unique_ptr<BlockInterpreter> blocks;
  std::optional<BasicSolver<ProgramSystem>> dense;  // where the block program does not serve
  std::unique_ptr<ForceSolver> force_solver;        // the prescribed drivers' power

  // Work space of one evaluation.
  Eigen::MatrixXd jac, mb;
  Eigen::VectorXd g, nu, mass_m, mass_j, mass_ax, mass_ay, reduced;
  std::vector<double> force_columns;
  // The last solution, the start of the next Newton solve.
  struct Last {
    bool valid = false;
    double t = 0;
    Eigen::VectorXd z, q, rheonomic;  // rheonomic: qd - B zd (the drivers' part)
    std::vector<double> inputs;       // the input slots at the last solution
  } last;
  // It, B and the block solver's memory as keep() found them.
  Last kept_last;
  Eigen::MatrixXd kept_b;
  BlockInterpreter::Memory kept_blocks;

  // Each body's mass, inertia and rotated centre of mass at q, for the mass kernel.
  void mass_data(const ForceModel& f, const Eigen::VectorXd& q) {
    const std::size_t nb = f.numbers.mass.size();
    mass_m.resize(nb);
    mass_j.resize(nb);
    mass_ax.resize(nb);
    mass_ay.resize(nb);
    for (std::size_t b = 0; b < nb; ++b) {
      const double c = std::cos(q[3 * b + 2]), s = std::sin(q[3 * b + 2]);
      const auto& com = f.numbers.com[b];
      mass_m[b] = f.numbers.mass[b];
      mass_j[b] = f.numbers.inertia[b];
      mass_ax[b] = c * com[0] - s * com[1];
      mass_ay[b] = s * com[0] + c * com[1];
    }
  }
  void mass_times(int nq, const double* v, double* out) const {
    K::_mass_times(static_cast<int>(mass_m.size()), nq, mass_m.data(), mass_j.data(),
                   mass_ax.data(), mass_ay.data(), v, out);
  }
};

ReducedDynamics::ReducedDynamics(const CompiledModel& model, const ForceModel& forces, double t0)
    : model_(model), forces_(forces), nq_(model.nq()) {
  const Mechanism& m = model.mechanism();
  const std::vector<int> free = m.free_drivers();
  nf_ = static_cast<int>(free.size());
  if (nf_ == 0)
    throw UsageError(m.source +
                     " has no free coordinates (`free:` lists the degrees of freedom "
                     "that the forces move); there is nothing to simulate");
  const int nj = static_cast<int>(m.joints.size());
  for (int d : free) {
    int row = 0;
    for (int c = 0; c < nj + d; ++c) row += m.constraints()[c]->equation_count();
    free_rows_.push_back(row);
  }
  impl_ = std::make_unique<Impl>(model, forces);
  // Prescribed drivers whose rate is not 0 do work: their efforts come from a force solve.
  for (std::size_t d = 0; d < m.drivers.size(); ++d)
    if (!m.drivers[d].free) impl_->force_solver = std::make_unique<ForceSolver>(model, forces);
  if (impl_->force_solver) impl_->force_solver->set_inputs(impl_->inputs.data());
  check_at_t0(t0);
}

ReducedDynamics::~ReducedDynamics() = default;

bool ReducedDynamics::fail(MotionFailure f, std::string reason) {
  failure_ = f;
  reason_ = std::move(reason);
  return false;
}


// 7.1's checks at t0, then the state there.
// Assembles with the joints and prescribed drivers alone (fixed_rows): the Gauss-Newton step
// of least (scaled) norm from q0, which finds the assembled position nearest the estimates.
Eigen::VectorXd ReducedDynamics::assemble_fixed(double t0, const std::vector<int>& fixed_rows) {
  Impl& w = *impl_;
  const int nc = model_.nc();
  const auto& scales = model_.symbolic().coordinate_scales;
  Eigen::VectorXd q = model_.q0(), phi(nc);
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(nc, nq_);
  for (int it = 0; it < 30; ++it) {
    w.eval.phi(q.data(), t0, phi.data());
    jac.setZero();
    w.eval.jacobian(q.data(), t0, jac);
    Eigen::MatrixXd js(fixed_rows.size(), nq_);
    Eigen::VectorXd rs(fixed_rows.size());
    for (std::size_t i = 0; i < fixed_rows.size(); ++i) {
      js.row(i) = jac.row(fixed_rows[i]);
      rs[i] = phi[fixed_rows[i]];
    }
    for (int k = 0; k < nq_; ++k) js.col(k) *= scales[k];
    if (!js.allFinite() || !rs.allFinite()) break;
    const Eigen::VectorXd step = js.completeOrthogonalDecomposition().solve(rs);
    double size = 0;
    for (int k = 0; k < nq_; ++k) {
      q[k] -= step[k] * scales[k];
      size = std::max(size, std::abs(step[k]));
    }
    if (size < 1e-13) break;
  }
  return q;
}

// The free items' counts and rank (docs/format.md: `free`), at the assembled position q.
void ReducedDynamics::check_counts_and_rank(double t0, const Eigen::VectorXd& q,
                                            const std::vector<int>& fixed_rows) {
  const Mechanism& m = model_.mechanism();
  const std::vector<int> free = m.free_drivers();
  const int nc = model_.nc();
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(nc, nq_);
  impl_->eval.jacobian(q.data(), t0, jac);
  const Eigen::MatrixXd scaled = scaled_jacobian(model_, jac);
  const int rank_fixed = rank_of(scaled, fixed_rows);
  const int dof = nq_ - rank_fixed;
  const int equations = static_cast<int>(fixed_rows.size());
  const std::string counts =
      std::to_string(nq_) + " coordinates less " +
      (rank_fixed == equations ? std::to_string(equations) + " joint and driver equations"
                               : std::to_string(equations) + " joint and driver equations, of "
                                                             "which " +
                                     std::to_string(rank_fixed) + " are independent here");
  const Constraint& first = m.drivers[free.front()];
  if (nf_ != dof || nc != nq_)
    throw InputError(m.source, "free", first.loc,
                     "the mechanism has " + std::to_string(dof) + " degree" +
                         (dof == 1 ? "" : "s") + " of freedom (" + counts + ") but " +
                         std::to_string(nf_) + " free item" + (nf_ == 1 ? "" : "s") +
                         ": list exactly one free item per degree of freedom" +
                         (nc != nq_ && nf_ == dof
                              ? " (and remove the redundant joints: the minimal-coordinates "
                                "method needs independent constraints)"
                              : ""));
  std::vector<int> rows = fixed_rows;
  for (int k = 0; k < nf_; ++k) {
    rows.push_back(free_rows_[k]);
    if (rank_of(scaled, rows) < static_cast<int>(rows.size())) {
      const Constraint& c = m.drivers[free[k]];
      throw InputError(m.source, c.item, c.loc,
                       "this free item adds nothing to the rank of Phi_q at t0 (the mechanism "
                       "has " +
                           std::to_string(dof) + " degree" + (dof == 1 ? "" : "s") +
                           " of freedom; this item's quantity is already fixed by the joints, "
                           "the drivers and the free items before it): choose another "
                           "coordinate");
    }
  }
}

void ReducedDynamics::check_at_t0(double t0) {
  const Mechanism& m = model_.mechanism();
  check_tables_hold(m, t0);  // else the first solve would blame a value0
  const std::vector<int> free = m.free_drivers();
  Impl& w = *impl_;
  std::vector<int> fixed_rows;
  for (int r = 0; r < model_.nc(); ++r)
    if (std::find(free_rows_.begin(), free_rows_.end(), r) == free_rows_.end())
      fixed_rows.push_back(r);
  const Eigen::VectorXd q = assemble_fixed(t0, fixed_rows);
  check_counts_and_rank(t0, q, fixed_rows);
  // The state at t0: value0 (default: the quantity at the assembled position) and v0.
  Eigen::VectorXd z0(nf_), zd0(nf_);
  w.free_values.run(q.data(), nullptr, t0, model_.params().data(), z0.data());
  for (int k = 0; k < nf_; ++k) {
    const Constraint& c = m.drivers[free[k]];
    if (c.free->value0) z0[k] = model_.geometry_number(*c.free->value0, c.item + " value0");
    zd0[k] = model_.geometry_number(c.free->v0, c.item + " v0");
  }
  w.last.q = q;
  w.last.valid = false;
  initial_.t = t0;
  // A value0 far from the quantity at the assembled position is reached by continuation, as
  // a generated dynamics() with a fresh work space reaches it (docs/embedding.md, "First
  // solves and branches"): steps of at most 0.25 rad (an angle) or 0.1 length scales (a
  // length, a distance), each solved from the last and checked against its prediction.
  Eigen::VectorXd at_q(nf_);
  w.free_values.run(q.data(), nullptr, t0, model_.params().data(), at_q.data());
  const int steps = continuation_steps(model_, free_rows_, at_q, z0);
  if (steps > kernels::ReportKernel::_kMaxContinuationSteps)
    throw InputError(m.source, "free", m.drivers[free.front()].loc,
                     "the free items' value0 lie more than " +
                         std::to_string(kernels::ReportKernel::_kMaxContinuationSteps) +
                         " continuation steps from their values at the q0 pose: give q0 near "
                         "the position at value0");
  // A failure's diagnosis starts again from the assembled position.
  const auto refuse = [&] {
    w.last.q = q;
    w.last.valid = false;
    report_t0_failure(t0);
  };
  for (int i = 1; i < steps; ++i) {
    const Eigen::VectorXd z = at_q + (z0 - at_q) * (static_cast<double>(i) / steps);
    if (!solve(t0, z.data(), zd0.data(), initial_)) refuse();
  }
  const bool assembled = solve(t0, z0.data(), zd0.data(), initial_);
  condition0_ = condition_;
  if (!assembled) refuse();
}

// The state at t0 did not solve: the input is at fault (exit 2), and this says where.
void ReducedDynamics::report_t0_failure(double t0) {
  const Mechanism& m = model_.mechanism();
  const std::vector<int> free = m.free_drivers();
  Impl& w = *impl_;
  if (failure_ == MotionFailure::kReducedMass) {
    // It assembled: the fault is a free item that moves no mass, the one whose diagonal
    // of B^T M B is the smallest.
    int worst = 0;
    for (int k = 1; k < nf_; ++k)
      if (b_.col(k).dot(w.mb.col(k)) < b_.col(worst).dot(w.mb.col(worst))) worst = k;
    const Constraint& c = m.drivers[free[worst]];
    throw InputError(m.source, c.item, c.loc,
                     "this free coordinate carries no inertia at " + format_time(t0) +
                         " (it moves only massless bodies): " + reason_);
  }
  // Where the file's own value0 does not assemble, the file is at fault (exit 2). The item
  // blamed is the first whose value0 does not assemble when the free items take theirs one
  // at a time, in `free:` order, from the assembled position (the others at their assembled
  // values), not merely the first item that has a value0.
  const std::string reason = reason_;
  const Eigen::VectorXd q = w.last.q;  // the assembled position (a failed solve keeps it)
  Eigen::VectorXd z(nf_);
  const Eigen::VectorXd zd = Eigen::VectorXd::Zero(nf_);
  w.free_values.run(q.data(), nullptr, t0, model_.params().data(), z.data());
  std::string before;  // the items already at their value0
  for (int k = 0; k < nf_; ++k) {
    const Constraint& c = m.drivers[free[k]];
    if (!c.free->value0) continue;
    z[k] = model_.geometry_number(*c.free->value0, c.item + " value0");
    w.last.q = q;
    w.last.valid = false;
    MotionState trial;
    if (!solve(t0, z.data(), zd.data(), trial) && failure_ != MotionFailure::kReducedMass)
      throw InputError(
          m.source, c.item + " value0", c.free->value0->loc,
          "the mechanism does not assemble with this free coordinate at its value0" +
              (before.empty() ? std::string() : " (with " + before + " at value0 too)") + " at " +
              format_time(t0) + ": " + reason_);
    before += (before.empty() ? "" : ", ") + c.item;
  }
  w.last.q = q;
  w.last.valid = false;
  for (int k = 0; k < nf_; ++k) {
    const Constraint& c = m.drivers[free[k]];
    if (c.free->value0)
      throw InputError(m.source, c.item + " value0", c.free->value0->loc,
                       "the mechanism does not assemble with the free coordinates at their "
                       "value0 at " +
                           format_time(t0) + ": " + reason);
  }
  throw InputError(m.source, "free", m.drivers[free.front()].loc,
                   "the mechanism does not assemble at " + format_time(t0) + ": " + reason);
}

// A singular position (Phi_q lost rank: the block solver's singular pivot, or the condition
// estimate) or a solution on another assembly branch (a block's determinant changed sign, or
// the position jumped off the prediction): both mean the motion reached or crossed a position
// where q is not a function of z. The reason names the free coordinates' values and the
// constraints that became dependent (those of the failed block, else of all Phi_q, at the
// last iterate).
std::string ReducedDynamics::singular_reason(double t, const MotionState& out, bool branch,
                                             int block, const std::string& detail) {
  const Mechanism& m = model_.mechanism();
  Impl& w = *impl_;
  w.jac.setZero(nq_, nq_);
  w.eval.jacobian(out.q.data(), t, w.jac);
  std::string rows;
  if (w.jac.allFinite()) {
    if (block >= 0 && w.blocks) {
      const Block& b = model_.structure().plans[block].block;
      rows = singular_rows(model_, w.jac, b.rows, b.cols);
    } else {
      rows = singular_rows(model_, w.jac);
    }
  }
  std::string at;
  for (int k = 0; k < nf_; ++k)
    at += (k ? ", " : "") + m.drivers[m.free_drivers()[k]].name + " = " +
          format_number(out.z[k]);
  if (branch)
    return "the position solve left its assembly branch at " + at + detail +
           ": the motion reached a singular position, where Phi_q loses rank and the minimal "
           "coordinates cannot tell the branches apart" +
           rows;
  return "the mechanism reached a singular position at " + at + detail +
         ", where Phi_q loses rank and q is not a function of the free coordinates" + rows;
}

bool ReducedDynamics::singular_failure(double t, const MotionState& out, bool branch, int block,
                                       const std::string& detail) {
  return fail(branch ? MotionFailure::kBranch : MotionFailure::kPosition,
              singular_reason(t, out, branch, block, detail));
}

std::string ReducedDynamics::singular_diagnosis(double t, const double* z, const double* zd) {
  MotionState s;
  if (!solve(t, z, zd, s))
    return failure_ == MotionFailure::kPosition || failure_ == MotionFailure::kBranch ? reason_
                                                                                       : "";
  if (!(condition_ > kNearSingular * condition0_)) return "";
  failure_ = MotionFailure::kPosition;
  reason_ = singular_reason(t, s, false, -1,
                            " (condition estimate of Phi_q " + format_estimate(condition_) +
                                ", " + format_estimate(condition0_) + " at t0)");
  return reason_;
}

double* ReducedDynamics::input_slots() { return impl_->inputs.data(); }

bool ReducedDynamics::evaluate(double t, const double* z, const double* zd, MotionState& out) {
  return solve(t, z, zd, out);
}

// q, qd and c (the acceleration at zdd = 0) from the inputs set, by the block program (or the
// dense solves); `condition` is Phi_q's scaled condition estimate there.
bool ReducedDynamics::solve_kinematics(double t, MotionState& out, double& condition) {
  Impl& w = *impl_;
  if (w.blocks) {
    const auto r = w.blocks->solve_step(out.q.data(), t, out.qd.data(), out.qdd.data(),
                                        block_options());
    if (const auto status = static_cast<Status>(r.status); status != Status::kConverged) {
      if (status == Status::kSingular || status == Status::kBranchJump)
        return singular_failure(t, out, status == Status::kBranchJump, r.block);
      const char* phase = BlockInterpreter::to_string(w.blocks->failed_phase());
      return fail(
          status == Status::kNonFinite ? MotionFailure::kNonFinite : MotionFailure::kPosition,
          std::string(phase) + " solve failed: " + to_string(status));
    }
    condition = r.rcond > 0 ? 1 / static_cast<double>(r.rcond) : 1;
  } else {
    if (auto r = w.dense->position(out.q, t); !r) {
      if (r.status == Status::kSingular || r.status == Status::kBranchJump)
        return singular_failure(t, out, r.status == Status::kBranchJump, -1);
      return fail(r.status == Status::kNonFinite ? MotionFailure::kNonFinite
                                                 : MotionFailure::kPosition,
                  std::string("position solve failed: ") + r.message());
    }
    auto rv = w.dense->velocity(out.q, t, out.qd);
    if (!rv) return fail(MotionFailure::kPosition, std::string("velocity solve: ") + rv.message());
    condition = rv.condition;
    if (auto ra = w.dense->acceleration(out.q, out.qd, t, out.qdd); !ra)
      return fail(MotionFailure::kPosition, std::string("acceleration solve: ") + ra.message());
  }
  return true;
}

// B = dq/dz, the generalized forces at c, and the reduced accelerations (zdd, qdd = c + B zdd).
bool ReducedDynamics::reduce(double t, MotionState& out) {
  const Mechanism& m = model_.mechanism();
  const std::vector<int> free = m.free_drivers();
  Impl& w = *impl_;
  // B: Phi_q B = E = -Phi_z, the free rows' unit vectors (their equations are quantity - z),
  // but 2 z for a distance (|d|^2 - z^2); one factorization for all columns.
  Eigen::MatrixXd e = Eigen::MatrixXd::Zero(nq_, nf_);
  for (int k = 0; k < nf_; ++k)
    e(free_rows_[k], k) = is_distance(m.drivers[free[k]]) ? 2 * out.z[k] : 1;
  if (nq_ <= 48) {
    b_ = Eigen::PartialPivLU<Eigen::MatrixXd>(w.jac).solve(e);
  } else {
    Eigen::SparseMatrix<double> sparse = w.jac.sparseView();
    Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(sparse);
    if (lu.info() != Eigen::Success)
      return singular_failure(t, out, false, -1, " (Phi_q could not be factored)");
    b_ = lu.solve(e);
  }
  // g = Q^A + the inertia forces at qdd = c; then the reduced accelerations.
  w.g.resize(nq_);
  w.applied.run(out.q.data(), out.qd.data(), t, model_.params().data(), w.g.data());
  add_inertia_forces(forces_.numbers, static_cast<int>(m.bodies.size()), out.q.data(),
                     out.qd.data(), out.qdd.data(), w.g.data());
  w.mass_data(forces_, out.q);
  w.mb.resize(nq_, nf_);
  for (int k = 0; k < nf_; ++k) w.mass_times(nq_, b_.col(k).data(), w.mb.col(k).data());
  w.reduced.resize(nf_ * nf_);
  out.zdd.resize(nf_);
  const double ratio = K::_reduced_accelerations(nq_, nf_, b_.data(), w.mb.data(), w.g.data(),
                                                 w.reduced.data(), out.zdd.data(),
                                                 out.qdd.data());
  if (!b_.allFinite() || !w.g.allFinite() || std::isnan(ratio))
    return fail(MotionFailure::kNonFinite,
                "a non-finite value in the generalized forces or dq/dz (a load, a table or the "
                "state)");
  if (!(ratio > 1e-13)) {
    // Which free items are to blame, from B^T M B itself (the factorization stops at its
    // first bad pivot and leaves no trace of the others): those whose own reduced mass
    // b_k^T M b_k is 0 against the largest; else the first whose column depends on the
    // earlier ones' (it moves only what they move).
    const Eigen::MatrixXd mz = b_.transpose() * w.mb;
    const double largest = mz.diagonal().cwiseAbs().maxCoeff();
    std::string names;
    for (int k = 0; k < nf_; ++k)
      if (!(mz(k, k) > 1e-13 * largest))
        names += (names.empty() ? "" : ", ") + m.drivers[free[k]].item;
    std::string why = "a free coordinate moves no mass (" + names + ")";
    if (names.empty()) {
      for (int k = 1; k < nf_ && names.empty(); ++k) {
        const Eigen::MatrixXd lead = mz.topLeftCorner(k + 1, k + 1);
        const Eigen::VectorXd ev =
            Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(lead).eigenvalues();
        if (ev.minCoeff() > 1e-13 * ev.cwiseAbs().maxCoeff()) continue;
        names = m.drivers[free[k]].item;
        std::string earlier;
        for (int j = 0; j < k; ++j) earlier += (j ? ", " : "") + m.drivers[free[j]].item;
        why = "a free coordinate moves only the mass that the others move (" + names + ", with " +
              earlier + ")";
      }
      if (names.empty()) why = "the free coordinates' reduced masses are too far apart";
    }
    return fail(MotionFailure::kReducedMass, "the reduced mass B^T M B is singular (pivot ratio " +
                                                 format_estimate(ratio) + "): " + why);
  }
  return true;
}

bool ReducedDynamics::solve(double t, const double* z, const double* zd, MotionState& out) {
  const Mechanism& m = model_.mechanism();
  const std::vector<int> free = m.free_drivers();
  Impl& w = *impl_;
  failure_ = MotionFailure::kNone;
  reason_.clear();
  if (const std::string table = table_outside(m, t); !table.empty())
    return fail(MotionFailure::kOutsideTable, "t lies outside " + table);
  for (int k = 0; k < nf_; ++k) {
    if (!std::isfinite(z[k]) || !std::isfinite(zd[k]))
      return fail(MotionFailure::kNonFinite, "the state is not finite");
    w.inputs[3 * free[k]] = z[k];
    w.inputs[3 * free[k] + 1] = zd[k];
    w.inputs[3 * free[k] + 2] = 0;  // c: the acceleration at zdd = 0
  }
  out.t = t;
  out.z = Eigen::Map<const Eigen::VectorXd>(z, nf_);
  out.zd = Eigen::Map<const Eigen::VectorXd>(zd, nf_);
  // Newton's start: the last solution moved along B by the change in z, and along the
  // prescribed drivers' rates by the change in t.
  out.q = w.last.q;
  if (w.last.valid) out.q += b_ * (out.z - w.last.z) + (t - w.last.t) * w.last.rheonomic;
  const Eigen::VectorXd predicted = out.q;
  out.qd.resize(nq_);
  out.qdd.resize(nq_);
  const auto& scales = model_.symbolic().coordinate_scales;
  double condition = 1;
  if (!solve_kinematics(t, out, condition)) return false;
  w.jac.setZero(nq_, nq_);
  w.eval.jacobian(out.q.data(), t, w.jac);
  condition_ = condition;
  if (condition > kSingularCondition) return singular_failure(t, out, false, -1);
  // A run-time input driver's value set anew since the last solve (equilibrium, modes,
  // linearize, Python's dynamics): the prediction knows nothing of it, so this solve, like the
  // first, is not checked against it.
  bool inputs_moved = false;
  for (std::size_t d = 0; w.last.valid && d < m.drivers.size(); ++d)
    if (m.drivers[d].law.input && !m.drivers[d].free)
      inputs_moved = inputs_moved || w.inputs[3 * d] != w.last.inputs[3 * d];
  if (w.last.valid && !inputs_moved) {
    // The branch check: the solution must agree with the first-order prediction to far better
    // than the predicted change itself (the miss is second order in the step).
    double change = 0, miss = 0;
    for (int k = 0; k < nq_; ++k) {
      const double inv = model_.symbolic().coordinate_kinds[k] == CoordinateKind::kAngle
                             ? 1.0
                             : 1 / scales[k];
      change = std::max(change, std::abs(predicted[k] - w.last.q[k]) * inv);
      miss = std::max(miss, std::abs(out.q[k] - predicted[k]) * inv);
    }
    if (miss > kBranchJumpFraction * change + 1e-9)
      return singular_failure(t, out, true, -1,
                              " (it misses the prediction from the last position by " +
                                  format_estimate(miss) + ", the predicted change being " +
                                  format_estimate(change) + ")");
  }
  if (!reduce(t, out)) return false;
  w.last.valid = true;
  w.last.t = t;
  w.last.z = out.z;
  w.last.q = out.q;
  w.last.rheonomic = out.qd - b_ * out.zd;
  w.last.inputs = w.inputs;
  return true;
}

void ReducedDynamics::keep() {
  Impl& w = *impl_;
  w.kept_last = w.last;
  w.kept_b = b_;
  if (w.blocks) w.blocks->save(w.kept_blocks);
}

void ReducedDynamics::restore() {
  Impl& w = *impl_;
  w.last = w.kept_last;
  b_ = w.kept_b;
  if (w.blocks) w.blocks->restore(w.kept_blocks);
}

Energy ReducedDynamics::energy(const MotionState& s) {
  Impl& w = *impl_;
  const Mechanism& m = model_.mechanism();
  Energy e;
  w.mass_data(forces_, s.q);
  Eigen::VectorXd mv(nq_), qnc(nq_);
  w.mass_times(nq_, s.qd.data(), mv.data());
  e.kinetic = 0.5 * s.qd.dot(mv);
  w.potential.run(s.q.data(), nullptr, s.t, model_.params().data(), &e.potential);
  w.nonconservative.run(s.q.data(), s.qd.data(), s.t, model_.params().data(), qnc.data());
  e.power = s.qd.dot(qnc);
  if (w.force_solver) {
    // The prescribed drivers' power, effort times rate: -lambda_r nu_r over their rows.
    for (int k = 0; k < nf_; ++k) {
      const int d = m.free_drivers()[k];
      w.inputs[3 * d] = s.z[k];
      w.inputs[3 * d + 1] = s.zd[k];
    }
    w.nu.resize(model_.nc());
    w.eval.nu(s.q.data(), s.t, w.nu.data());
    double p = 0;
    if (w.force_solver->solve(s.t, s.q, s.qd, s.qdd, w.force_columns)) {
      const Eigen::VectorXd& lambda = w.force_solver->lambda();
      for (int r = 0; r < model_.nc(); ++r)
        if (std::find(free_rows_.begin(), free_rows_.end(), r) == free_rows_.end())
          p -= lambda[r] * w.nu[r];
    } else {
      p = std::numeric_limits<double>::quiet_NaN();
    }
    e.power += p;
  }
  return e;
}

}  // namespace kinegen::codegen
