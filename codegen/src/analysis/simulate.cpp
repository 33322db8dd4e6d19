// Forward dynamics over a time grid on SUNDIALS CVODE (see analysis/simulate.hpp).
#include "kinegen/codegen/analysis/simulate.hpp"

#include <cvode/cvode.h>
#include <cvode/cvode_proj.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunlinsol/sunlinsol_spgmr.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <cmath>
#include <limits>
#include <memory>

#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/base/interrupt.hpp"

namespace kinegen::codegen {

namespace {

// Minimal coordinates: y = [z, zd].
class MinimalFormulation : public MotionFormulation {
 public:
  MinimalFormulation(const CompiledModel& model, const ForceModel& forces, double t0)
      : model_(model), dynamics_(model, forces, t0), state_(dynamics_.initial()) {}

  int size() const override { return 2 * dynamics_.nf(); }
  Eigen::VectorXd initial() const override {
    Eigen::VectorXd y(size());
    y << dynamics_.initial().z, dynamics_.initial().zd;
    return y;
  }
  Eigen::VectorXd scales() const override {
    const Mechanism& m = model_.mechanism();
    const int nf = dynamics_.nf();
    Eigen::VectorXd s(2 * nf);
    const std::vector<int> free = m.free_drivers();
    for (int k = 0; k < nf; ++k) {
      // An angle in radians; a length (distance, x, y) in the mechanism's length scale.
      const std::string type = m.drivers[free[k]].type_name();
      const bool angle = type == "absolute_angle" || type == "relative_angle";
      s[k] = s[nf + k] = angle ? 1.0 : model_.symbolic().length_scale;
    }
    return s;
  }
  bool rhs(double t, const double* y, double* ydot) override {
    const int nf = dynamics_.nf();
    if (!dynamics_.evaluate(t, y, y + nf, state_)) return false;
    for (int k = 0; k < nf; ++k) {
      ydot[k] = y[nf + k];
      ydot[nf + k] = state_.zdd[k];
    }
    return true;
  }
  const MotionState& state() const override { return state_; }
  Energy energy() override { return dynamics_.energy(state_); }
  MotionFailure failure() const override { return dynamics_.failure(); }
  const std::string& reason() const override { return dynamics_.reason(); }
  std::string diagnose(double t, const double* y) override {
    const std::string cause = dynamics_.singular_diagnosis(t, y, y + dynamics_.nf());
    return cause.empty() ? cause : cause + advice();
  }
  std::string advice() const override {
    const MotionFailure f = dynamics_.failure();
    if (f == MotionFailure::kPosition || f == MotionFailure::kBranch ||
        f == MotionFailure::kReducedMass)
      return "; the minimal-coordinates method cannot pass a singular position: use --method "
             "augmented";
    return "";
  }

 private:
  const CompiledModel& model_;
  ReducedDynamics dynamics_;
  MotionState state_;
};

// The smallest step CVODE may take, as a fraction of the run (Integration::set_stop_time).
constexpr double kMinStep = 1e-12;

// Whether the model has springs or dampers: stiff enough that BDF is the safer default.
bool has_springs(const Mechanism& m) {
  for (const Load& l : m.forces.loads)
    if (l.kind == Load::Kind::kSpringDamper || l.kind == Load::Kind::kRotationalSpringDamper)
      return true;
  return false;
}

// One CVODE run: the formulation plus the work integral as the last state entry.
class Integration {
 public:
  Integration(const CompiledModel& model, const ForceModel& forces, MotionFormulation& f,
              const SimulateOptions& o, double t0)
      : model_(model), f_(f), o_(o), n_(f.size()) {
    if (SUNContext_Create(nullptr, &ctx_) != 0) throw std::runtime_error("SUNContext_Create");
    y_ = N_VNew_Serial(n_ + 1, ctx_);
    atol_ = N_VNew_Serial(n_ + 1, ctx_);
    const Eigen::VectorXd y0 = f.initial(), scale = f.scales();
    for (int k = 0; k < n_; ++k) {
      NV_Ith_S(y_, k) = y0[k];
      NV_Ith_S(atol_, k) = o.atol * scale[k];
    }
    NV_Ith_S(y_, n_) = 0;
    std::vector<double> ydot(n_);
    if (!f.rhs(t0, y0.data(), ydot.data()))
      throw AnalysisError(model.mechanism().source + ": simulation failed at " + format_time(t0) +
                          ": " + f.reason() + f.advice());
    const Energy e = f.energy();
    energy0_ = e.kinetic + e.potential;
    kinetic0_ = e.kinetic;
    potential0_ = e.potential;
    t0_ = t0;
    // The work's absolute tolerance: --atol times the energy scale at t0.
    NV_Ith_S(atol_, n_) = o.atol * std::max({std::abs(e.kinetic) + std::abs(e.potential), 1.0});
    const bool bdf = o.integrator == Integrator::kBdf ||
                     (o.integrator == Integrator::kAuto &&
                      (has_springs(model.mechanism()) || f.has_projection()));
    if (f.has_projection() && o.integrator == Integrator::kAdams)
      throw UsageError(
          "--method augmented projects onto the constraints after each step, which CVODE "
          "supports with BDF only: use --integrator bdf (or auto)");
    cvode_ = CVodeCreate(bdf ? CV_BDF : CV_ADAMS, ctx_);
    // CVODE prints its errors to stderr by default; a failure is reported once, as one
    // `error:` line naming the time and the cause (advance()), so its own text is dropped.
    check(CVodeSetErrHandlerFn(cvode_, &Integration::quiet, nullptr), "CVodeSetErrHandlerFn");
    check(CVodeInit(cvode_, &Integration::rhs, t0, y_), "CVodeInit");
    check(CVodeSVtolerances(cvode_, o.rtol, atol_), "CVodeSVtolerances");
    check(CVodeSetUserData(cvode_, this), "CVodeSetUserData");
    check(CVodeSetMaxNumSteps(cvode_, o.max_steps), "CVodeSetMaxNumSteps");
    check(CVodeSetMaxErrTestFails(cvode_, 20), "CVodeSetMaxErrTestFails");
    if (bdf && f.has_projection()) {
      // A formulation in all of q (2 nq states, 487 for the N = 40 four-bar): Newton's systems
      // by matrix-free GMRES, each product a difference of two evaluations, rather than a
      // dense difference Jacobian of n evaluations and its n^3 factorization (6x faster
      // there, and it passed singular positions the dense Jacobian's did not, at 1e-13).
      ls_ = SUNLinSol_SPGMR(y_, SUN_PREC_NONE, 20, ctx_);
      check(CVodeSetLinearSolver(cvode_, ls_, nullptr), "CVodeSetLinearSolver");
    } else if (bdf) {
      a_ = SUNDenseMatrix(n_ + 1, n_ + 1, ctx_);
      ls_ = SUNLinSol_Dense(y_, a_, ctx_);
      check(CVodeSetLinearSolver(cvode_, ls_, a_), "CVodeSetLinearSolver");
    } else {
      nls_ = SUNNonlinSol_FixedPoint(y_, 0, ctx_);
      check(CVodeSetNonlinearSolver(cvode_, nls_), "CVodeSetNonlinearSolver");
    }
    if (f.has_projection()) check(CVodeSetProjFn(cvode_, &Integration::project), "CVodeSetProjFn");
    if (!model.symbolic().stop_when.is_zero() || model.mechanism().stop_when) {
      stop_ = std::make_unique<Program>(lower({model.symbolic().stop_when}, model.symbols()));
      stop_eval_ = std::make_unique<ProgramEvaluator<double>>(*stop_);
      if (!model.symbolic().stop_force_columns.empty())
        stop_forces_ = std::make_unique<ForceSolver>(model, forces);
      check(CVodeRootInit(cvode_, 1, &Integration::root), "CVodeRootInit");
      int up = 1;  // from below
      check(CVodeSetRootDirection(cvode_, &up), "CVodeSetRootDirection");
      check(CVodeSetNoInactiveRootWarn(cvode_), "CVodeSetNoInactiveRootWarn");
    }
  }
  ~Integration() {
    if (cvode_) CVodeFree(&cvode_);
    if (ls_) SUNLinSolFree(ls_);
    if (a_) SUNMatDestroy(a_);
    if (nls_) SUNNonlinSolFree(nls_);
    N_VDestroy(y_);
    N_VDestroy(atol_);
    SUNContext_Free(&ctx_);
  }
  Integration(const Integration&) = delete;
  Integration& operator=(const Integration&) = delete;

  // The end, and the smallest step: a failure that persists down to a step of kMinStep of
  // the run is not one a smaller step avoids (a singular position the minimal coordinates
  // cannot pass: the evaluations fail just past it, and the steps would shrink towards it
  // without end).
  void set_stop_time(double t0, double t1) {
    check(CVodeSetStopTime(cvode_, t1), "CVodeSetStopTime");
    check(CVodeSetMinStep(cvode_, kMinStep * (t1 - t0)), "CVodeSetMinStep");
  }

  // Advances to `t`; returns the time reached (a root's, when stopped) and whether a root
  // stopped it. Throws AnalysisError on failure.
  double advance(double t, bool& rooted) {
    double reached = t;
    const int flag = CVode(cvode_, t, y_, &reached, CV_NORMAL);
    rooted = flag == CV_ROOT_RETURN;
    if (interrupt_) throw *interrupt_;
    if (flag < 0) {
      double now = reached;
      CVodeGetCurrentTime(cvode_, &now);
      throw AnalysisError(model_.mechanism().source + ": simulation failed at " +
                          format_time(now) + ": " + failure_cause(flag, now));
    }
    return reached;
  }

  // Why CVODE returned `flag` at `now`: the failed evaluation's reason; else the formulation's
  // diagnosis at the state reached (a singular position the steps could not pass); else the
  // flag.
  std::string failure_cause(int flag, double now) {
    if (flag == CV_TOO_MUCH_WORK) return "the integrator took more steps than its limit";
    if (!last_failure_.empty()) return last_failure_;
    std::vector<double> y(n_ + 1);
    N_Vector v = N_VMake_Serial(n_ + 1, y.data(), ctx_);
    std::string diagnosis;
    if (CVodeGetDky(cvode_, now, 0, v) == CV_SUCCESS) diagnosis = f_.diagnose(now, y.data());
    N_VDestroy(v);
    if (!diagnosis.empty()) return diagnosis;
    std::string cause = std::string("the integrator failed (") + CVodeGetReturnFlagName(flag) + ")";
    if (flag == CV_ERR_FAILURE || flag == CV_CONV_FAILURE)
      cause += " (the error test or the corrector failed repeatedly)";
    return cause;
  }

  // The row at time t from the integrator's y there (dense output, or the root's state).
  SimulatedRow row(double t, ForceSolver* force_solver) {
    const int n = n_;
    std::vector<double> y(n), ydot(n);
    for (int k = 0; k < n; ++k) y[k] = NV_Ith_S(y_, k);
    if (!f_.rhs(t, y.data(), ydot.data()))
      throw AnalysisError(model_.mechanism().source + ": simulation failed at " + format_time(t) +
                          ": " + f_.reason() + f_.advice());
    const MotionState& s = f_.state();
    SimulatedRow r;
    r.state.t = t;
    r.state.q = s.q;
    r.state.qd = s.qd;
    r.state.qdd = s.qdd;
    r.z = s.z;
    r.zd = s.zd;
    r.zdd = s.zdd;
    const Energy e = f_.energy();
    r.kinetic = e.kinetic;
    r.potential = e.potential;
    r.work = NV_Ith_S(y_, n);
    r.balance = e.kinetic + e.potential - r.work - energy0_;
    check_balance(t, r);
    if (force_solver && !force_solver->solve(t, s.q, s.qd, s.qdd, r.state.forces))
      throw AnalysisError(model_.mechanism().source + ": force analysis failed at " +
                          format_time(t) + ": Phi_q is singular (scaled condition estimate " +
                          format_estimate(force_solver->condition()) + ")");
    return r;
  }

 private:
  static void check(int flag, const char* what) {
    if (flag < 0) throw std::runtime_error(std::string(what) + " failed");
  }
  // The energy balance as a guard: a run whose balance is off by far more than its tolerance
  // allows (10% of the energy exchanged, or 1000 rtol) has lost its accuracy, and its rows
  // from here on would be a wrong answer (the minimal coordinates stall at a fold of q(z), as
  // a slider-crank moved by its slider at a dead centre: the kinetic energy gone, no Newton
  // failure). The energy exchanged: the largest change of the terms since t0 at any state
  // the integrator evaluated (rhs()), not only at the rows, which may all sit where the
  // energy is back at its start (a pendulum's swing stopped at its far end).
  void note_energy(const Energy& e, double work) {
    energy_scale_ = std::max(energy_scale_, std::abs(e.kinetic - kinetic0_) +
                                                std::abs(e.potential - potential0_) +
                                                std::abs(work));
  }
  void check_balance(double t, const SimulatedRow& r) {
    note_energy({r.kinetic, r.potential}, r.work);
    const double rounding = 1e-9 * (std::abs(r.kinetic) + std::abs(r.potential));
    const double allowed = std::max(0.1, 1e3 * o_.rtol) * energy_scale_ + rounding;
    if (t == t0_ || !(std::abs(r.balance) > allowed)) return;
    throw AnalysisError(
        model_.mechanism().source + ": simulation failed at " + format_time(t) +
        ": the energy balance is off by " + format_estimate(std::abs(r.balance)) + " (" +
        format_estimate(100 * std::abs(r.balance) / energy_scale_) +
        "% of the energy exchanged): the integration lost its accuracy" +
        (o_.method == Method::kMinimal
             ? "; the minimal-coordinates method does this where the free coordinates stop "
               "determining q (a singular position): use --method augmented"
             : ""));
  }
  static void quiet(int, const char*, const char*, char*, void*) {}
  static int rhs(double t, N_Vector y, N_Vector ydot, void* data) {
    auto* self = static_cast<Integration*>(data);
    if (self->o_.interrupted && self->o_.interrupted()) {
      self->last_failure_ = "interrupted";
      return -1;
    }
    try {  // Ctrl-C between rows far apart; no exception may cross CVODE's C frames
      interruption_point();
    } catch (const Interrupted& e) {
      self->interrupt_ = std::make_unique<Interrupted>(e);
      return -1;
    }
    const double* yv = N_VGetArrayPointer(y);
    double* dv = N_VGetArrayPointer(ydot);
    if (!self->f_.rhs(t, yv, dv)) {
      // Recoverable: CVODE retries with a smaller step; if the motion really reaches the
      // failure, it gives up and this is the cause named.
      self->last_failure_ = self->f_.reason() + self->f_.advice();
      return self->f_.failure() == MotionFailure::kOutsideTable ? -1 : 1;
    }
    self->last_failure_.clear();  // a failure that a smaller step avoided is no cause
    const Energy e = self->f_.energy();
    dv[self->n_] = e.power;
    if (std::isfinite(e.power)) self->note_energy(e, yv[self->n_]);
    if (!std::isfinite(dv[self->n_])) {
      self->last_failure_ = "the power of the loads and drivers is not finite";
      return 1;
    }
    return 0;
  }
  static int root(double t, N_Vector y, double* g, void* data) {
    auto* self = static_cast<Integration*>(data);
    const double* yv = N_VGetArrayPointer(y);
    std::vector<double> ydot(self->n_);
    if (!self->f_.rhs(t, yv, ydot.data())) return 1;
    const MotionState& s = self->f_.state();
    std::vector<double> params = self->model_.params();
    if (self->stop_forces_) {
      std::vector<double> columns;
      if (!self->stop_forces_->solve(t, s.q, s.qd, s.qdd, columns)) return 1;
      for (int c : self->model_.symbolic().stop_force_columns) params.push_back(columns[c]);
    }
    self->stop_eval_->run(s.q.data(), s.qd.data(), t, params.data(), g);
    return std::isfinite(g[0]) ? 0 : 1;
  }
  static int project(double t, N_Vector y, N_Vector corr, double /*eps*/, N_Vector err,
                     void* data) {
    auto* self = static_cast<Integration*>(data);
    N_VConst(0.0, corr);
    if (!self->f_.project(t, N_VGetArrayPointer(y), N_VGetArrayPointer(corr))) return 1;
    if (err && !self->f_.project_error(t, N_VGetArrayPointer(err))) return 1;
    return 0;
  }

  const CompiledModel& model_;
  MotionFormulation& f_;
  const SimulateOptions& o_;
  int n_;
  SUNContext ctx_ = nullptr;
  N_Vector y_ = nullptr, atol_ = nullptr;
  void* cvode_ = nullptr;
  SUNMatrix a_ = nullptr;
  SUNLinearSolver ls_ = nullptr;
  SUNNonlinearSolver nls_ = nullptr;
  double energy0_ = 0, kinetic0_ = 0, potential0_ = 0, energy_scale_ = 0, t0_ = 0;
  std::string last_failure_;
  std::unique_ptr<Interrupted> interrupt_;  // the rhs saw an interruption point throw
  std::unique_ptr<Program> stop_;
  std::unique_ptr<ProgramEvaluator<double>> stop_eval_;
  std::unique_ptr<ForceSolver> stop_forces_;
};

}  // namespace

std::unique_ptr<MotionFormulation> minimal_formulation(const CompiledModel& model,
                                                       const ForceModel& forces, double t0) {
  return std::make_unique<MinimalFormulation>(model, forces, t0);
}

std::unique_ptr<MotionFormulation> make_formulation(Method method, const CompiledModel& model,
                                                    const ForceModel& forces, double t0) {
  return method == Method::kAugmented ? augmented_formulation(model, forces, t0)
                                      : minimal_formulation(model, forces, t0);
}

void run_simulation(const CompiledModel& model, const ForceModel& forces, const TimeGrid& grid,
                    const std::function<void(const SimulatedRow&)>& sink,
                    const SimulateOptions& options) {
  std::unique_ptr<MotionFormulation> f = make_formulation(options.method, model, forces, grid.t0);
  Integration integration(model, forces, *f, options, grid.t0);
  integration.set_stop_time(grid.t0, grid.t1);
  std::unique_ptr<ForceSolver> force_solver;
  if (options.forces_columns) force_solver = std::make_unique<ForceSolver>(model, forces);
  OutputEvaluator outputs(model);
  const auto emit = [&](double t) {
    SimulatedRow r = integration.row(t, force_solver.get());
    const auto& points = model.mechanism().points;
    for (std::size_t p = 0; p < points.size(); ++p) {
      const int b = 3 * points[p].body;
      r.state.points.push_back(point_state(r.state.q.segment<3>(b), r.state.qd.segment<3>(b),
                                           r.state.qdd.segment<3>(b), model.point_offsets()[p]));
    }
    outputs.evaluate(t, r.state.q, r.state.qd, r.state.qdd, r.state.outputs);
    sink(r);
    if (options.progress) options.progress(t);
    interruption_point();
  };
  emit(grid.t0);
  for (int k = 1; k <= grid.steps; ++k) {
    bool rooted = false;
    const double t = integration.advance(grid.at(k), rooted);
    emit(t);
    if (rooted) return;
  }
}

std::string simulate_csv_header(const Mechanism& m, const std::vector<std::string>& forces) {
  std::string h = csv_header(m, forces, {});
  h.pop_back();
  for (const std::string& z : free_names(m)) h += "," + z + "," + z + ".v," + z + ".a";
  h += ",energy.kinetic,energy.potential,energy.work,energy.balance";
  return h + "\n";
}

std::string simulate_csv_row(const SimulatedRow& row, int num_bodies) {
  std::string s = csv_row(row.state, num_bodies);
  s.pop_back();
  for (int k = 0; k < row.z.size(); ++k)
    s += "," + format_number(row.z[k]) + "," + format_number(row.zd[k]) + "," +
         format_number(row.zdd[k]);
  for (double v : {row.kinetic, row.potential, row.work, row.balance}) s += "," + format_number(v);
  return s + "\n";
}

SimulateOptions simulate_options(double rtol, double atol, const std::string& method,
                                 const std::string& integrator, const std::string& prefix) {
  if (!std::isfinite(rtol) || !(rtol > 0) || rtol >= 1)
    throw UsageError(prefix + "rtol must be a finite number in (0, 1), not " +
                     format_number(rtol));
  if (!std::isfinite(atol) || !(atol > 0))
    throw UsageError(prefix + "atol must be a finite number above 0, not " + format_number(atol));
  if (method != "minimal" && method != "augmented")
    throw UsageError(prefix + "method must be 'minimal' or 'augmented', not '" + method + "'");
  if (integrator != "auto" && integrator != "bdf" && integrator != "adams")
    throw UsageError(prefix + "integrator must be 'auto', 'bdf' or 'adams', not '" + integrator +
                     "'");
  SimulateOptions o;
  o.rtol = rtol;
  o.atol = atol;
  o.method = method == "augmented" ? Method::kAugmented : Method::kMinimal;
  o.integrator = integrator == "bdf"     ? Integrator::kBdf
                 : integrator == "adams" ? Integrator::kAdams
                                         : Integrator::kAuto;
  return o;
}

}  // namespace kinegen::codegen
