// The analysis' time loop (run_analysis): a position, velocity and acceleration solve per
// time, by the block program or on all of Phi_q, with the checks between steps; then points,
// outputs, sensitivities and forces of each row.
#include "kinegen/codegen/analysis/analysis.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <kinegen/block_options.hpp>
#include <kinegen/motion.hpp>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "diagnosis.hpp"
#include "kinegen/codegen/analysis/block_interpreter.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "kinegen/codegen/analysis/spatial.hpp"
#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/model/table.hpp"

namespace kinegen::codegen {

using namespace analysis_detail;

namespace {

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
class TimeLoop {
 public:
  TimeLoop(S& solver, const CompiledModel& model, const AnalysisOptions& options,
           BlockInterpreter* blocks)
      : solver_(solver),
        model_(model),
        options_(options),
        blocks_(blocks),
        file_(model.mechanism().source),
        outputs_(model),
        sensitivity_(options.sensitivity) {
    all_coordinates_.resize(model.nq());
    for (int k = 0; k < model.nq(); ++k) all_coordinates_[k] = k;
    row_.q = model.q0();
    row_.qd = Eigen::VectorXd::Zero(model.nq());
    row_.qdd = Eigen::VectorXd::Zero(model.nq());
    if (sensitivity_) phi_p_eval_ = std::make_unique<ProgramEvaluator<double>>(sensitivity_->phi_p);
    if (options.forces) force_solver_ = std::make_unique<ForceSolver>(model, *options.forces);
    if (model.mechanism().spatial) spatial_ = std::make_unique<SpatialAnalysis>(model);
    // kinegen::Solver's defaults in double, converted as its block path converts them.
    block_options_ = block_options_from<BlockInterpreter::Options>(default_options<double>());
  }

  void run(const TimeGrid& grid, const std::function<void(const StateRow&)>& sink) {
    for (int k = 0; k <= grid.steps; ++k) {
      interruption_point();  // Ctrl-C: the rows so far are the caller's
      const double t = grid.at(k);
      if (const std::string table = table_outside(model_.mechanism(), t); !table.empty())
        throw AnalysisError(file_ + ": position analysis failed at " + format_time(t) +
                            ": t lies outside " + table);
      if (k == 0)
        solve_first(t);
      else
        advance(t);
      row_.t = t;
      if (sensitivity_)
        solve_sensitivities(solver_, *sensitivity_, *phi_p_eval_, model_, t, row_,
                            [this](const char* stage, double at, Result r) { fail(stage, at, r); });
      complete_row(t);
      sink(row_);
    }
  }

 private:
  // Why a step was refused: a solve that failed (its phase and result), or a jump (`jump`,
  // what the check found).
  struct Refusal {
    const char* stage = "position";
    Result result;
    std::string jump;
  };

  // The coordinates the start of a step predicts.
  const std::vector<int>& predicted() const {
    return blocks_ ? blocks_->newton_coordinates() : all_coordinates_;
  }

  // The first row: from the file's q0 estimates, by the drivers' continuation where the
  // solver has it (the dense path, as a generated Solver's first solve: docs/embedding.md),
  // then the checks of the assembly. Where q0 fits (after whole turns of the angle drivers)
  // no continuation runs, and the block path's first solve starts from q0 as a generated
  // Solver's does, to the same bits.
  void solve_first(double t) {
    if (spatial_) {
      // Spatial files: the drivers' own continuation from the q0 pose (docs/format.md,
      // Spatial mechanisms), then the ordinary solve at t below.
      spatial_->first_position(row_.q, t);
      continued_ = true;
    } else if constexpr (std::is_same_v<S, analysis_detail::Solver>) {
      const double steps = solver_.first_steps(row_.q, t);
      if (!(steps <= 1)) {
        if (const Result r = solver_.first_position(row_.q, t); !r) fail("position", t, r);
        continued_ = true;
      }
    }
    Refusal refused;
    const auto solve = [&] {
      if (!(blocks_ ? solve_blocks(t, true, refused) : solve_dense(t, true, refused)))
        fail(refused.stage, t, refused.result);
    };
    solve();
    if (blocks_) {
      first_solve_ = false;
      // As on the dense path, but a changed estimate is solved again from scratch (then
      // analyze and a Solver started from the file's q0 differ by whole turns).
      const Eigen::VectorXd before = row_.q;
      if (!continued_) keep_turns_of_estimates(solver_, model_, row_.q, t);
      if (row_.q != before) {
        blocks_->reset();
        solve();
      }
      check_redundancy(model_, row_.q, t, options_);
      check_assembly(model_, row_.q, options_);
    }
    accept(t);
  }

  // The step from the last accepted row to t, in sub-steps while it is refused (substeps,
  // kinegen/motion.hpp: what Solver::step does with the same substep_halvings).
  void advance(double t) {
    Refusal refused;
    const double from = last_.t;
    const auto attempt = [&](double to) {
      // A failure in a sub-step names the step it belongs to.
      if ((to != t || last_.t != from) && substep_note_.empty())
        substep_note_ = " (in sub-steps of the step from " + format_time(from) + " to " +
                        format_time(t) + ", down to 1/" +
                        format_number(std::ldexp(
                            1.0, std::min(options_.substep_halvings, kMaxSubstepHalvings))) +
                        " of it)";
      predict(to);
      const bool solved =
          blocks_ ? solve_blocks(to, false, refused) : solve_dense(to, false, refused);
      if (solved && !(options_.check_jumps && jumped(to, refused))) {
        accept(to);
        return true;
      }
        refused_q_ = row_.q;  // the messages describe the refused solution
      return false;
    };
    const auto restore = [&] {
      row_.q = last_.q;
      row_.qd = last_.qd;
      row_.qdd = last_.qdd;
    };
    double at = t;
    if (substeps(from, t, options_.substep_halvings, attempt, restore, at)) {
      substep_note_.clear();
      return;
    }
    row_.q = refused_q_;
    if (refused.jump.empty()) fail(refused.stage, at, refused.result);
    throw AnalysisError(
        file_ + ": position analysis failed at " + format_time(at) + substep_note_ + ": " +
        refused.jump +
        (options_.substep_halvings > 0
             ? ": the motion passes a singular configuration here (a change point, where "
               "branches meet, or a toggle), or it moves too fast for the mechanism to follow"
             : ": Newton left the assembly branch it started on, or the step is too coarse "
               "to tell; use smaller steps (--steps)"));
  }

  // The runtime's predictor from the last accepted state keeps Newton on its branch.
  void predict(double to) {
    const double h = to - last_.t;
    const bool jerk = accepted_ > 1;
    const TaylorPredictor<double> predict(h, h_before_, jerk);
    // The block path predicts what Solver::step predicts, the coordinates Newton iterates:
    // the others are assigned, and their start value sets how their sin and cos rotate.
    for (int c : predicted())
      row_.q[c] = predict(row_.q[c], row_.qd[c], row_.qdd[c], jerk ? qdd_before_[c] : 0.0);
  }

  // Makes the solved row_ at t the last accepted state (the next step's start).
  void accept(double t) {
    if (accepted_ > 0) {
      qdd_before_ = last_.qdd;
      h_before_ = t - last_.t;
    }
    last_.t = t;
    last_.q = row_.q;
    last_.qd = row_.qd;
    last_.qdd = row_.qdd;
    ++accepted_;
    if (!blocks_) previous_sign_ = solver_.jacobian_sign();
  }

  // The block program's step at t (Solver::step's); false, with the reason, when it failed.
  // A solve that succeeds near a toggle (Newton converging onto it) ends the analysis.
  bool solve_blocks(double t, bool first, Refusal& refused) {
    // Solver::step's solve: the first one iterates to convergence whatever the options.
    BlockInterpreter::Options o = block_options_;
    if (first) o.fixed_iterations = 0;
    Result r = block_result(
        blocks_->solve_step(row_.q.data(), t, row_.qd.data(), row_.qdd.data(), o), model_.nq());
    if (!r) {
      refused = {BlockInterpreter::to_string(blocks_->failed_phase()), r, {}};
      return false;
    }
    if (r.condition > options_.max_condition) {
      r.status = Status::kSingular;
      fail("position", t, r);
    }
    if (spatial_) spatial_->check_branches(row_.q, t);
    return true;
  }

  // Position, velocity and acceleration on the dense or sparse Phi_q; false, with the reason,
  // when one failed. The first row checks the assembly between position and velocity.
  bool solve_dense(double t, bool first, Refusal& refused) {
    const auto refuse = [&](const char* stage, Result r) {
      refused = {stage, r, {}};
      return false;
    };
    if (auto r = solver_.position(row_.q, t); !r) return refuse("position", r);
    first_solve_ = false;
    if (spatial_) spatial_->check_branches(row_.q, t);
    if (first) {
      // After a continuation every angle has its continued value, as in a generated Solver.
      if (!continued_) keep_turns_of_estimates(solver_, model_, row_.q, t);
      check_redundancy(model_, row_.q, t, options_);
      check_assembly(model_, row_.q, options_);
    }
    if (auto r = solver_.velocity(row_.q, t, row_.qd); !r) {
      return refuse("velocity", r);
    } else if (r.condition > options_.max_condition) {
      // Newton converges (slowly) onto a toggle point, where Phi_q is singular only in the
      // limit: velocities there are meaningless, so it counts as singular.
      r.status = Status::kSingular;
      fail("position", t, r);
    }
    if (auto r = solver_.acceleration(row_.q, row_.qd, t, row_.qdd); !r)
      return refuse("acceleration", r);
    return true;
  }

  // The runtime's jump test (kinegen/motion.hpp), the one Solver::step applies, and the sign
  // of det(Phi_q) on the dense path: whether the solution at t left the motion, and how.
  bool jumped(double t, Refusal& refused) const {
    const auto& scales = model_.symbolic().coordinate_scales;
    const auto inv_scale = [&](int k) { return 1 / scales[k]; };
    const MotionCheck motion = check_motion(
        predicted(), t - last_.t, last_.q, last_.qd, last_.qdd, row_.q, row_.qd, row_.qdd,
        inv_scale, options_.jump_fraction, std::numeric_limits<double>::epsilon());
    if (motion.jumped()) {
      refused.jump = "the solution jumped (scaled change " + format_number(motion.change) +
                     " since " + format_time(last_.t) + " disagrees with the velocities by " +
                     format_number(motion.miss) + ")";
      return true;
    }
    const int sign = blocks_ ? 0 : solver_.jacobian_sign();
    if (previous_sign_ != 0 && sign != 0 && sign != previous_sign_) {
      refused.jump = "det(Phi_q) changed sign since " + format_time(last_.t) +
                     ": the solution crossed a singular configuration or jumped to another "
                     "assembly branch";
      return true;
    }
    return false;
  }

  // The row's points, outputs, their sensitivities and the forces.
  void complete_row(double t) {
    row_.points.clear();
    const auto& points = model_.mechanism().points;
    for (std::size_t p = 0; p < points.size() && !spatial_; ++p) {
      const int b = 3 * points[p].body;
      row_.points.push_back(point_state(row_.q.segment<3>(b), row_.qd.segment<3>(b),
                                        row_.qdd.segment<3>(b), model_.point_offsets()[p]));
    }
    outputs_.evaluate(t, row_.q, row_.qd, row_.qdd, row_.outputs);
    if (sensitivity_) {
      point_sensitivities(model_, *sensitivity_, row_.q, row_.dq_dp, row_.dpoints_dp);
      output_sensitivities(model_, *sensitivity_, t, row_.q, row_.dq_dp, row_.doutputs_dp);
    }
    if (force_solver_) solve_forces(t);
  }

  void solve_forces(double t) {
    if (!force_solver_->solve(t, row_.q, row_.qd, row_.qdd, row_.forces)) {
      // Singular, or a value that is not finite (a load, a weight): each its own message.
      if (!force_solver_->singular())
        throw AnalysisError(file_ + ": force analysis failed at " + format_time(t) + ": " +
                            force_solver_->failure_cause(t, row_.q, row_.qd, row_.qdd));
      throw AnalysisError(file_ + ": force analysis failed at " + format_time(t) +
                          ": Phi_q is singular (scaled condition estimate " +
                          format_estimate(force_solver_->condition()) + ", the limit " +
                          format_estimate(1 / force_min_rcond<double>()) +
                          "), so no finite efforts hold the motion (a toggle or dead-centre "
                          "position)");
    }
    if (!force_warned_ && force_solver_->condition() > options_.force_warning && options_.warn) {
      options_.warn(file_ + ": at " + format_time(t) +
                    " the scaled condition estimate of Phi_q is " +
                    format_estimate(force_solver_->condition()) + " (above " +
                    format_estimate(options_.force_warning) +
                    "): the mechanism nears a toggle, where efforts and reactions grow without "
                    "bound");
      force_warned_ = true;
    }
  }

  [[noreturn]] void fail(const char* stage, double t, Result r) const {
    // Newton that ends near a singular Phi_q (as at a toggle, where it converges only
    // linearly) is reported as singular, as a solved position there is. Newton stalled at a
    // step that vanished, short of the residual: the constraints contradict each other (a
    // redundant model slightly off), whatever the iteration count says.
    if (r.status == Status::kMaxIterations && r.condition > options_.max_condition)
      r.status = Status::kSingular;
    if (r.status == Status::kMaxIterations && r.step <= 1e-10) r.status = Status::kInconsistent;
    std::string message = file_ + ": " + stage + " analysis failed at " + format_time(t) +
                          substep_note_ + ": " + r.message();
    if (r.status == Status::kMaxIterations || r.status == Status::kInconsistent) {
      if (r.status == Status::kMaxIterations)
        message += " in " + std::to_string(r.iterations) + " iterations (last scaled step " +
                   format_estimate(r.step) + "); the mechanism may not assemble here";
      message += largest_residual(model_, row_.q, t) + " (condition estimate of Phi_q " +
                 format_estimate(r.condition) + " at the last iterate)";
    }
    if (r.status == Status::kSingular) message += singular_message(stage, t, r);
    // Where the value that is not finite comes from, at the last solved state and this t.
    if (r.status == Status::kNonFinite) {
      const bool before = last_.q.size() > 0;  // a row solved before this one
      message += nonfinite_rows(model_, before ? last_.q : model_.q0(),
                                before ? last_.qd : Eigen::VectorXd(model_.nq()).setZero(), t);
    }
    if (first_solve_ && std::string(stage) == "position" && r.status != Status::kNonFinite)
      message += first_solve_hint();
    throw AnalysisError(message);
  }

  // What a singular failure's message adds: the constraints involved, the block.
  std::string singular_message(const char* stage, double t, const Result& r) const {
    std::string message;
    if (!blocks_)
      message += singular_diagnosis(model_, solver_, r);
    else if (r.block >= 0) {  // the failed block's rows and columns: q is solved up to it
      const Block& b = blocks_->structure().plans[r.block].block;
      if (static_cast<int>(b.cols.size()) <= kMaxDiagnosedNq)
        message += singular_rows(model_, jacobian_at(model_, row_.q, t), b.rows, b.cols);
    } else if (model_.nq() <= kMaxDiagnosedNq)
      message += singular_rows(model_, jacobian_at(model_, row_.q, t));
    if (r.block >= 0 && blocks_)
      message += "; block " + std::to_string(r.block) + " of the block solver";
    if (std::string(stage) == "position")
      message +=
          "; a toggle or dead-centre position (a driver past what the mechanism can "
          "reach), or constraints that leave a motion undriven";
    return message;
  }

  // What a failed first solve's message adds: a word on the file's q0 estimates.
  std::string first_solve_hint() const {
    const Eigen::VectorXd& q0 = model_.q0();
    return q0.cwiseAbs().maxCoeff() == 0
               ? "; every q0 estimate in the file is 0: Newton starts from all bodies on "
                 "top of each other, where Phi_q is singular; give each body's q0 near its "
                 "assembled position"
               : "; this is the first solve, from the q0 estimates in the file: check "
                 "that they are near an assembled position (a far-off q0 can start "
                 "Newton at a singular or unreachable point)";
  }

  S& solver_;
  const CompiledModel& model_;
  const AnalysisOptions& options_;
  BlockInterpreter* blocks_;
  const std::string& file_;
  std::vector<int> all_coordinates_;
  StateRow row_;
  OutputEvaluator outputs_;
  bool continued_ = false;   // the first solve followed the drivers from q0 (first_position)
  bool first_solve_ = true;  // the first position solve starts from the file's q0
  const SensitivityModel* sensitivity_;
  std::unique_ptr<ProgramEvaluator<double>> phi_p_eval_;
  std::unique_ptr<ForceSolver> force_solver_;
  std::unique_ptr<SpatialAnalysis> spatial_;  // spatial files only
  bool force_warned_ = false;
  BlockInterpreter::Options block_options_;
  // The last accepted state (a row, or a sub-step between rows), where the next step starts.
  struct Accepted {
    double t = 0;
    Eigen::VectorXd q, qd, qdd;
  } last_;
  int accepted_ = 0;            // rows and sub-steps accepted so far
  Eigen::VectorXd qdd_before_;  // the acceleration one step before `last_` (the jerk)
  double h_before_ = 0;
  int previous_sign_ = 0;
  Eigen::VectorXd refused_q_;  // the last refused solution
  std::string substep_note_;   // what a failure after sub-steps adds to its time
};

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
  // Spatial files run on the block program as their generated headers do, but never on the
  // sparse solver (their first solve's continuation is SpatialAnalysis's, on the dense one).
  const bool spatial = model.mechanism().spatial;
  if (options.block_solver && model.nq() == model.nc() &&
      BlockInterpreter::supported(model.structure()))
    blocks = std::make_unique<BlockInterpreter>(model);
  if (!spatial && model.nq() == model.nc() && model.nq() > options.sparse_above_nq) {
    LargeSolver solver{RhsSystem(model)};
    TimeLoop<LargeSolver>(solver, model, options, blocks.get()).run(grid, sink);
  } else {
    Solver solver{RhsSystem(model)};
    TimeLoop<Solver>(solver, model, options, blocks.get()).run(grid, sink);
  }
}

}  // namespace kinegen::codegen
