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

#include "kinegen/codegen/analysis/breakpoints.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/base/interrupt.hpp"

namespace kinegen::codegen {

namespace {

// Minimal coordinates: y = [z, zd].
class MinimalFormulation : public MotionFormulation {
 public:
  MinimalFormulation(const CompiledModel& model, const ForceModel& forces, double t0)
      : model_(model),
        dynamics_(model, forces, t0),
        state_(dynamics_.initial()),
        programs_(model.force_programs(forces)),
        applied_(programs_->applied),
        nonconservative_(programs_->nonconservative) {
    applied_.set_inputs(dynamics_.input_slots());
    nonconservative_.set_inputs(dynamics_.input_slots());
  }

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
  void keep() override { dynamics_.keep(); }
  void restore() override { dynamics_.restore(); }
  Energy energy() override { return dynamics_.energy(state_); }
  double activity(const Energy& e) override {
    const MotionState& s = state_;
    const int nq = static_cast<int>(s.q.size());
    const double* params = model_.params().data();
    Eigen::VectorXd applied(nq), qnc(nq);
    applied_.run(s.q.data(), s.qd.data(), s.t, params, applied.data());
    nonconservative_.run(s.q.data(), s.qd.data(), s.t, params, qnc.data());
    // Q^A = -V_q + Q^nc: the potential's forces are Q^A - Q^nc; the prescribed drivers' power
    // is what e.power holds beyond the loads'.
    return s.qd.cwiseProduct(qnc).cwiseAbs().sum() +
           s.qd.cwiseProduct(applied - qnc).cwiseAbs().sum() +
           std::abs(e.power - s.qd.dot(qnc));
  }
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
  std::shared_ptr<const ForcePrograms> programs_;  // the compile stage's
  ProgramEvaluator<double> applied_, nonconservative_;
};

// The smallest step CVODE may take at time t, in ulps of t: a failure that persists down to it
// is not one a smaller step avoids (a singular position the minimal coordinates cannot pass:
// the evaluations fail just past it, and the steps would shrink towards it without end). It
// follows t alone, never the run's length or its grid.
constexpr double kMinStepUlps = 100;
constexpr double kEps = std::numeric_limits<double>::epsilon();

// The energy balance's bound (docs/dynamics.md, "The energy balance"): at every internal step
// |balance| <= min(C (rtol + atol/S) (S + X), kDriftCap S), S the largest kinetic + |potential|
// so far, X the energy exchanged (the integral of the sum of |power|). C per method, chosen by
// measurement so that no correct run comes near it (docs/dynamics.md).
constexpr double kBalanceConstantMinimal = 1000;
constexpr double kBalanceConstantAugmented = 10000;
constexpr double kDriftCap = 1e-3;

double balance_constant(Method m) {
  return m == Method::kAugmented ? kBalanceConstantAugmented : kBalanceConstantMinimal;
}

// Whether the model has springs or dampers: stiff enough that BDF is the safer default.
bool has_springs(const Mechanism& m) {
  for (const Load& l : m.forces.loads)
    if (l.kind == Load::Kind::kSpringDamper || l.kind == Load::Kind::kRotationalSpringDamper)
      return true;
  return false;
}

// stop_when at one time: its value, its rate along the motion, and its error bound E (rtol
// times its scale plus the share of the state's atol).
struct StopSample {
  double t = 0, g = 0, rate = 0, bound = 0;
  std::vector<double> forces;  // the force columns it reads (their rates by differences)
};

// One CVODE run, driven one internal step at a time: the formulation plus the work and the
// energy exchanged as the last two state entries; after each step the energy balance is
// checked and stop_when is searched for its first crossing over the step.
class Integration {
 public:
  // breakpoints: the times in (t0, t1) where a driver's or a load's function is not smooth,
  // ascending; no step spans one (the integrator stops there and starts afresh).
  Integration(const CompiledModel& model, const ForceModel& forces, MotionFormulation& f,
              const SimulateOptions& o, double t0, double t1, std::vector<double> breakpoints)
      : model_(model),
        f_(f),
        o_(o),
        n_(f.size()),
        t0_(t0),
        t1_(t1),
        tcur_(t0),
        breakpoints_(std::move(breakpoints)) {
    if (SUNContext_Create(nullptr, &ctx_) != 0) throw std::runtime_error("SUNContext_Create");
    y_ = N_VNew_Serial(n_ + 2, ctx_);
    atol_ = N_VNew_Serial(n_ + 2, ctx_);
    const Eigen::VectorXd y0 = f.initial(), scale = f.scales();
    for (int k = 0; k < n_; ++k) {
      NV_Ith_S(y_, k) = y0[k];
      NV_Ith_S(atol_, k) = o.atol * scale[k];
    }
    NV_Ith_S(y_, n_) = 0;
    NV_Ith_S(y_, n_ + 1) = 0;
    std::vector<double> ydot(n_);
    ++evaluations_;
    if (!f.rhs(t0, y0.data(), ydot.data())) throw failure(t0, f.reason() + f.advice());
    f.keep();
    const Energy e = f.energy();
    energy0_ = e.kinetic + e.potential;
    largest_energy_ = e.kinetic + std::abs(e.potential);
    atol_energy_ = o.atol * energy_scale(e.kinetic + std::abs(e.potential), forces,
                                         model.symbolic().length_scale);
    NV_Ith_S(atol_, n_) = NV_Ith_S(atol_, n_ + 1) = atol_energy_;
    const bool springs = has_springs(model.mechanism());
    const bool bdf = o.integrator == Integrator::kBdf ||
                     (o.integrator == Integrator::kAuto && (springs || f.has_projection()));
    integrator_ = bdf ? "BDF" : "Adams";
    if (o.integrator == Integrator::kAuto)
      integrator_ += bdf ? (springs ? " (auto: the model has springs or dampers)"
                                    : " (auto: the augmented method projects after each step)")
                         : " (auto: no springs or dampers)";
    if (f.has_projection() && o.integrator == Integrator::kAdams)
      throw UsageError(
          "--method augmented projects onto the constraints after each step, which CVODE "
          "supports with BDF only: use --integrator bdf (or auto)");
    cvode_ = CVodeCreate(bdf ? CV_BDF : CV_ADAMS, ctx_);
    // CVODE prints its errors to stderr by default; a failure is reported once, as one
    // `error:` line naming the time and the cause, so its own text is dropped.
    check(CVodeSetErrHandlerFn(cvode_, &Integration::quiet, nullptr), "CVodeSetErrHandlerFn");
    check(CVodeInit(cvode_, &Integration::rhs, t0, y_), "CVodeInit");
    check(CVodeSVtolerances(cvode_, o.rtol, atol_), "CVodeSVtolerances");
    check(CVodeSetUserData(cvode_, this), "CVodeSetUserData");
    check(CVodeSetMaxErrTestFails(cvode_, 20), "CVodeSetMaxErrTestFails");
    set_stop_time();
    if (bdf && f.has_projection()) {
      // A formulation in all of q (2 nq states, 487 for the N = 40 four-bar): Newton's systems
      // by matrix-free GMRES, each product a difference of two evaluations, rather than a
      // dense difference Jacobian of n evaluations and its n^3 factorization (6x faster
      // there, and it passed singular positions the dense Jacobian's did not, at 1e-13).
      ls_ = SUNLinSol_SPGMR(y_, SUN_PREC_NONE, 20, ctx_);
      check(CVodeSetLinearSolver(cvode_, ls_, nullptr), "CVodeSetLinearSolver");
    } else if (bdf) {
      a_ = SUNDenseMatrix(n_ + 2, n_ + 2, ctx_);
      ls_ = SUNLinSol_Dense(y_, a_, ctx_);
      check(CVodeSetLinearSolver(cvode_, ls_, a_), "CVodeSetLinearSolver");
    } else {
      nls_ = SUNNonlinSol_FixedPoint(y_, 0, ctx_);
      check(CVodeSetNonlinearSolver(cvode_, nls_), "CVodeSetNonlinearSolver");
    }
    if (f.has_projection()) check(CVodeSetProjFn(cvode_, &Integration::project), "CVodeSetProjFn");
    if (model.mechanism().stop_when) {
      const SymbolicModel& sym = model.symbolic();
      const StopPrograms& stop = model.stop_programs();
      has_rate_ = stop.has_rate;
      stop_ = &stop.program;
      stop_eval_ = std::make_unique<ProgramEvaluator<double>>(*stop_);
      stop_values_.resize(stop.size);
      if (!sym.stop_force_columns.empty())
        stop_forces_ = std::make_unique<ForceSolver>(model, forces);
      last_ = stop_sample(t0, nullptr);
      level_ = StopWhenLevel(last_.g, last_.bound);
      if (level_.stops_at_t0()) {
        stopped_ = true;
        stop_time_ = t0;
      }
    }
    set_step_limits(t0);
  }
  ~Integration() = default;  // release_ frees the SUNDIALS objects
  Integration(const Integration&) = delete;
  Integration& operator=(const Integration&) = delete;

  bool stopped() const { return stopped_; }
  double stop_time() const { return stop_time_; }

  // Steps until the solution covers t (its last step reaches t), or stop_when ended the run
  // before. Throws AnalysisError on failure.
  void cover(double t) {
    while (!stopped_ && tcur_ < t) step();
  }

  // The row at time t, within the last step (dense output).
  SimulatedRow row(double t, ForceSolver* force_solver) {
    std::vector<double> y;
    evaluate_at(t, y);
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
    r.work = y[n_];
    r.balance = e.kinetic + e.potential - r.work - energy0_;
    if (!std::isfinite(r.balance))
      throw failure(t, "the energy terms are not finite (a load, a table or the state)");
    if (force_solver && !force_solver->solve(t, s.q, s.qd, s.qdd, r.state.forces))
      throw AnalysisError(model_.mechanism().source + ": force analysis failed at " +
                          format_time(t) + ": Phi_q is singular (scaled condition estimate " +
                          format_estimate(force_solver->condition()) + ")");
    return r;
  }

  SimulateSummary summary() {
    SimulateSummary s;
    s.integrator = integrator_;
    s.steps = steps_;
    s.restarts = restarts_;
    long value = 0;
    if (CVodeGetNumErrTestFails(cvode_, &value) == CV_SUCCESS) s.error_test_failures = value;
    s.evaluations = evaluations_;
    s.largest_balance = largest_balance_;
    s.largest_balance_time = largest_balance_time_;
    s.largest_ratio = largest_ratio_;
    if (drift_excess_ > 0) {
      s.drifted = true;
      s.drift = "the energy balance passed its bound: |energy.balance| = " +
                format_estimate(drift_balance_) + " at " + format_time(drift_time_) + " (" +
                drift_limit_ + "); the rows are less accurate than --rtol asks (--allow-drift)";
    }
    s.stopped = stopped_;
    s.stop_time = stop_time_;
    s.stop_bound = stop_bound_;
    return s;
  }

 private:
  static void check(int flag, const char* what) {
    if (flag < 0) throw std::runtime_error(std::string(what) + " failed");
  }
  AnalysisError failure(double t, const std::string& cause) const {
    return AnalysisError(model_.mechanism().source + ": simulation failed at " + format_time(t) +
                         ": " + cause);
  }

  // The next stop: the first breakpoint after tcur_, else t1.
  void set_stop_time() {
    while (next_breakpoint_ < breakpoints_.size() &&
           !(breakpoints_[next_breakpoint_] > tcur_))
      ++next_breakpoint_;
    tstop_ = next_breakpoint_ < breakpoints_.size() ? std::min(breakpoints_[next_breakpoint_], t1_)
                                                   : t1_;
    check(CVodeSetStopTime(cvode_, tstop_), "CVodeSetStopTime");
  }

  // One internal step, then the checks at its end.
  void step() {
    if (tcur_ == tstop_ && tstop_ < t1_) {
      // At a breakpoint: the integrator starts afresh (order 1, no history across it), once
      // the rows up to it are written (the dense output of the last step goes with it).
      check(CVodeReInit(cvode_, tcur_, y_), "CVodeReInit");
      set_stop_time();
      ++restarts_;
    }
    if (steps_ >= o_.max_steps)
      throw failure(tcur_, "the integrator took " + std::to_string(o_.max_steps) +
                               " steps in all, its limit (a model too stiff for --integrator " +
                               (integrator_.rfind("BDF", 0) == 0 ? "bdf" : "adams") +
                               " at this tolerance; try another --integrator or --method)");
    double reached = tcur_;
    f_.restore();  // the rows and stop_when samples since the last step leave no trace
    const int flag = CVode(cvode_, tstop_, y_, &reached, CV_ONE_STEP);
    if (interrupt_) throw *interrupt_;
    if (flag < 0) {
      double now = reached;
      CVodeGetCurrentTime(cvode_, &now);
      throw failure(now, failure_cause(flag, now));
    }
    ++steps_;
    tcur_ = reached;
    std::vector<double> y(NV_DATA_S(y_), NV_DATA_S(y_) + n_ + 2), ydot(n_);
    ++evaluations_;
    if (!f_.rhs(reached, y.data(), ydot.data()))
      throw failure(reached, f_.reason() + f_.advice());
    f_.keep();
    check_energy(reached, y);
    if (stop_ && !stopped_) {
      const StopSample end = stop_sample(reached, &last_);
      scan(end);
    }
    set_step_limits(reached);
  }

  // The smallest step (kMinStepUlps of t) and the largest: --max-step, and stop_when's rule
  // |EXPR'| h <= (|EXPR| + E)/8 at the step's start.
  void set_step_limits(double t) {
    const double hmin = kMinStepUlps * kEps * std::abs(t);
    double hmax = o_.max_step > 0 ? o_.max_step : std::numeric_limits<double>::infinity();
    if (stop_ && !stopped_) {
      const double l = limit(last_);
      if (l > 0) hmax = std::min(hmax, l);
    }
    check(CVodeSetMaxStep(cvode_, 0), "CVodeSetMaxStep");  // none, while hmin changes
    check(CVodeSetMinStep(cvode_, hmin), "CVodeSetMinStep");
    if (std::isfinite(hmax))
      check(CVodeSetMaxStep(cvode_, std::max(hmax, 2 * hmin)), "CVodeSetMaxStep");
  }

  // The energy balance as a witness of the accuracy (see kBalanceConstantMinimal), at the
  // state f_ holds (time t, integrator state y).
  void check_energy(double t, const std::vector<double>& y) {
    const Energy e = f_.energy();
    const double balance = e.kinetic + e.potential - y[n_] - energy0_;
    const double exchanged = y[n_ + 1];
    if (!std::isfinite(balance))
      throw failure(t, "the energy terms are not finite (a load, a table or the state)");
    largest_energy_ = std::max(largest_energy_, e.kinetic + std::abs(e.potential));
    // Never below atol_E / rtol: below it the work's error control is absolute, and a start
    // from rest at zero potential has S = 0.
    const double s = std::max(largest_energy_, atol_energy_ / o_.rtol);
    if (std::abs(balance) > largest_balance_) {
      largest_balance_ = std::abs(balance);
      largest_balance_time_ = t;
    }
    const double tolerance =
        balance_constant(o_.method) * (o_.rtol + atol_energy_ / s) * (s + std::abs(exchanged));
    const double cap = kDriftCap * s;
    largest_ratio_ = std::max(largest_ratio_, std::abs(balance) / tolerance);
    if (std::abs(balance) <= std::min(tolerance, cap)) return;
    const std::string limit =
        cap < tolerance
            ? "0.1% of the energy scale S = " + format_estimate(s)
            : "the bound C (rtol + atol/S) (S + X) = " + format_estimate(tolerance) +
                  " that the tolerances allow, C = " +
                  format_estimate(balance_constant(o_.method)) + ", S = " + format_estimate(s) +
                  ", X = " + format_estimate(exchanged) + " the energy exchanged";
    if (o_.allow_drift) {
      const double excess = std::abs(balance) / std::min(tolerance, cap);
      if (excess > drift_excess_) {
        drift_excess_ = excess;
        drift_balance_ = std::abs(balance);
        drift_time_ = t;
        drift_limit_ = "past " + limit;
      }
      return;
    }
    // A singular position the formulation recognizes there is the cause to name (the minimal
    // coordinates lose their accuracy as q(z) folds, before any evaluation fails).
    if (o_.method == Method::kMinimal)
      if (const std::string cause = f_.diagnose(t, y.data()); !cause.empty())
        throw failure(t, cause);
    throw failure(
        t, "the energy balance is off by " + format_estimate(std::abs(balance)) + ", past " +
               limit + ": the integration lost its accuracy; try a tighter --rtol (now " +
               format_number(o_.rtol) + ") or another --integrator" +
               (o_.method == Method::kMinimal
                    ? " (or --method augmented, where the free coordinates stop determining q "
                      "at a singular position)"
                    : "") +
               "; --allow-drift makes this a warning");
  }

  // y at t within the last step (dense output), evaluated: f_.state() is the state there.
  void evaluate_at(double t, std::vector<double>& y) {
    y.assign(n_ + 2, 0.0);
    if (t == tcur_) {
      std::copy(NV_DATA_S(y_), NV_DATA_S(y_) + n_ + 2, y.begin());
    } else {
      N_Vector v = N_VMake_Serial(n_ + 2, y.data(), ctx_);
      const int flag = CVodeGetDky(cvode_, t, 0, v);
      N_VDestroy(v);
      if (flag != CV_SUCCESS)
        throw std::logic_error("CVodeGetDky outside the last step at " + format_time(t));
    }
    std::vector<double> ydot(n_);
    ++evaluations_;
    if (!f_.rhs(t, y.data(), ydot.data())) throw failure(t, f_.reason() + f_.advice());
  }

  // stop_when at the state f_ holds (time t); `before`: the sample before it, for the rates
  // of force columns (and of g when it has no exact rate).
  StopSample stop_sample(double t, const StopSample* before) {
    const MotionState& s = f_.state();
    const SymbolicModel& sym = model_.symbolic();
    std::vector<double> params = model_.params();
    StopSample out;
    out.t = t;
    if (stop_forces_) {
      std::vector<double> columns;
      if (!stop_forces_->solve(t, s.q, s.qd, s.qdd, columns))
        throw failure(t, "stop_when reads a force column, and the force analysis failed there "
                         "(Phi_q is singular)");
      for (int c : sym.stop_force_columns) {
        out.forces.push_back(columns[c]);
        params.push_back(columns[c]);
      }
    }
    stop_eval_->run(s.q.data(), s.qd.data(), t, params.data(), stop_values_.data());
    out.g = stop_values_[0];
    if (!std::isfinite(out.g)) {
      const Expr& e = *model_.mechanism().stop_when;
      throw AnalysisError(model_.mechanism().source +
                          (e.loc.line > 0 ? ":" + std::to_string(e.loc.line) : std::string()) +
                          ": stop_when: '" + e.text + "' is " + format_number(out.g) + " at " +
                          format_time(t) + ": the run cannot tell whether it crossed 0");
    }
    gscale_ = std::max(gscale_, std::abs(out.g));
    const double dt = before ? t - before->t : 0;
    const int nq = static_cast<int>(s.q.size());
    out.bound = stop_when_bound(gscale_, has_rate_ ? &stop_values_[2 + nq] : nullptr,
                                has_rate_ ? &stop_values_[2] : nullptr, sym.coordinate_scales, o_);
    if (has_rate_) {
      out.rate = stop_values_[1];
      for (int k = 0; k < nq; ++k) out.rate += stop_values_[2 + k] * s.qdd[k];
      for (std::size_t j = 0; j < out.forces.size(); ++j)
        if (dt > 0)
          out.rate += stop_values_[2 + 2 * nq + j] * (out.forces[j] - before->forces[j]) / dt;
    } else if (dt > 0) {
      out.rate = (out.g - before->g) / dt;
    }
    return out;
  }
  StopSample stop_sample_at(double t, const StopSample& before) {
    std::vector<double> y;
    evaluate_at(t, y);
    return stop_sample(t, &before);
  }

  // The longest step from s that the rule |EXPR'| h <= (|EXPR| + E)/8 allows: 0 when it gives
  // no scale (EXPR = 0 with no error bound yet), infinite for a constant EXPR.
  static double limit(const StopSample& s) {
    const double r = std::abs(s.rate);
    if (!std::isfinite(r)) return 0;
    if (!(r > 0)) return std::numeric_limits<double>::infinity();
    return (std::abs(s.g) + s.bound) / (8 * r);
  }

  // Searches the step from last_ to `end` for stop_when's first crossing, at sub-intervals
  // whose ends both satisfy the rule (on the dense output); sets stopped_ and stop_time_.
  void scan(const StopSample& end) {
    StopSample a = last_;
    const double floor = std::max(kMinStepUlps * kEps * std::abs(end.t), 1e-12 * (end.t - a.t));
    while (a.t < end.t) {
      double h = std::min(std::max(limit(a), floor), end.t - a.t);
      StopSample b;
      for (int tries = 0;; ++tries) {
        b = a.t + h >= end.t ? end : stop_sample_at(a.t + h, a);
        if (!(limit(b) < h) || h <= floor || tries >= 60) break;
        h = std::max(h / 2, floor);
      }
      if (crossing(a, b)) return;
      level_.see(b.g < 0);
      a = b;
    }
    last_ = end;
  }

  // Whether stop_when crosses its level (StopWhenLevel: 0, or its bound at t0) from below
  // between samples a and b (a sign change, or a local maximum at or above it between them);
  // if so, stops the run there.
  bool crossing(const StopSample& a, const StopSample& b) {
    const double level = level_.level();
    if (!(a.g < level)) return false;
    if (b.g >= level) return stop_between(a, b);
    if (has_rate_ && a.rate > 0 && b.rate < 0) {
      // A local maximum between them: where the rate changes sign (the Illinois method).
      StopSample lo = a, hi = b;
      double rlo = a.rate, rhi = b.rate;
      int side = 0;
      for (int it = 0; it < 200 && hi.t - lo.t > time_tolerance(hi.t); ++it) {
        double tm = hi.t - rhi * (hi.t - lo.t) / (rhi - rlo);
        if (!(tm > lo.t && tm < hi.t)) tm = 0.5 * (lo.t + hi.t);
        const StopSample m = stop_sample_at(tm, lo);
        if (m.g >= level) return stop_between(lo, m);
        if (m.rate > 0) {
          lo = m;
          rlo = m.rate;
          if (side == -1) rhi /= 2;
          side = -1;
        } else {
          hi = m;
          rhi = m.rate;
          if (side == 1) rlo /= 2;
          side = 1;
        }
      }
    }
    return false;
  }

  // The crossing between a (g < level) and b (g >= level), by the Illinois method on the dense
  // output: the run stops at the first time found with g >= level.
  bool stop_between(StopSample a, StopSample b) {
    const double level = level_.level();
    double ga = a.g - level, gb = b.g - level;
    int side = 0;
    for (int it = 0; it < 200 && b.t - a.t > time_tolerance(b.t); ++it) {
      double tm = b.t - gb * (b.t - a.t) / (gb - ga);
      if (!(tm > a.t && tm < b.t)) tm = 0.5 * (a.t + b.t);
      const StopSample m = stop_sample_at(tm, a);
      if (m.g >= level) {
        b = m;
        gb = m.g - level;
        if (side == 1) ga /= 2;
        side = 1;
      } else {
        a = m;
        ga = m.g - level;
        if (side == -1) gb /= 2;
        side = -1;
      }
    }
    stopped_ = true;
    stop_time_ = b.t;
    stop_bound_ = level_.bound();
    return true;
  }
  static double time_tolerance(double t) { return 4 * kEps * std::max(std::abs(t), 1e-300); }

  // Why CVODE returned `flag` at `now`: the failed evaluation's reason; else the formulation's
  // diagnosis at the state reached (a singular position the steps could not pass); else the
  // flag, with what it means.
  std::string failure_cause(int flag, double now) {
    if (!last_failure_.empty()) return last_failure_;
    std::vector<double> y(n_ + 2);
    N_Vector v = N_VMake_Serial(n_ + 2, y.data(), ctx_);
    std::string diagnosis;
    if (CVodeGetDky(cvode_, now, 0, v) == CV_SUCCESS) diagnosis = f_.diagnose(now, y.data());
    N_VDestroy(v);
    if (!diagnosis.empty()) return diagnosis;
    double h = 0;
    CVodeGetCurrentStep(cvode_, &h);
    std::string cause = std::string("the integrator failed (") + CVodeGetReturnFlagName(flag) + ")";
    if (flag == CV_ERR_FAILURE || flag == CV_CONV_FAILURE)
      cause += ": its error test or corrector failed repeatedly, down to a step of " +
               format_estimate(std::abs(h)) + " (" + integrator_ +
               "); try another --integrator, a looser --atol or another --method";
    return cause;
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
    ++self->evaluations_;
    if (!self->f_.rhs(t, yv, dv)) {
      // Recoverable: CVODE retries with a smaller step; if the motion really reaches the
      // failure, it gives up and this is the cause named.
      self->last_failure_ = self->f_.reason() + self->f_.advice();
      return self->f_.failure() == MotionFailure::kOutsideTable ? -1 : 1;
    }
    self->last_failure_.clear();  // a failure that a smaller step avoided is no cause
    const Energy e = self->f_.energy();
    dv[self->n_] = e.power;
    dv[self->n_ + 1] = self->f_.activity(e);
    if (!std::isfinite(dv[self->n_]) || !std::isfinite(dv[self->n_ + 1])) {
      self->last_failure_ = "the power of the loads and drivers is not finite";
      return 1;
    }
    return 0;
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
  double t0_, t1_, tcur_, tstop_ = 0;
  std::vector<double> breakpoints_;
  std::size_t next_breakpoint_ = 0;
  long restarts_ = 0;
  SUNContext ctx_ = nullptr;
  N_Vector y_ = nullptr, atol_ = nullptr;
  void* cvode_ = nullptr;
  SUNMatrix a_ = nullptr;
  SUNLinearSolver ls_ = nullptr;
  SUNNonlinearSolver nls_ = nullptr;
  // Frees the SUNDIALS objects above, also when the constructor throws half-way (then the
  // members are destroyed but no destructor body runs): declared after them.
  struct Release {
    Integration* self;
    ~Release() {
      Integration& i = *self;
      if (i.cvode_) CVodeFree(&i.cvode_);
      if (i.ls_) SUNLinSolFree(i.ls_);
      if (i.a_) SUNMatDestroy(i.a_);
      if (i.nls_) SUNNonlinSolFree(i.nls_);
      if (i.y_) N_VDestroy(i.y_);
      if (i.atol_) N_VDestroy(i.atol_);
      if (i.ctx_) SUNContext_Free(&i.ctx_);
    }
  } release_{this};
  std::string integrator_;
  long steps_ = 0, evaluations_ = 0;
  // The energy balance.
  double energy0_ = 0, largest_energy_ = 0, atol_energy_ = 0;
  double largest_balance_ = 0, largest_balance_time_ = 0, largest_ratio_ = 0;
  double drift_excess_ = 0, drift_balance_ = 0, drift_time_ = 0;
  std::string drift_limit_;
  std::string last_failure_;
  std::unique_ptr<Interrupted> interrupt_;  // the rhs saw an interruption point throw
  // stop_when.
  const Program* stop_ = nullptr;  // the compile stage's stop_when program
  std::unique_ptr<ProgramEvaluator<double>> stop_eval_;
  std::vector<double> stop_values_;
  std::unique_ptr<ForceSolver> stop_forces_;
  bool has_rate_ = false, stopped_ = false;
  double stop_time_ = 0, stop_bound_ = 0, gscale_ = 0;
  StopWhenLevel level_{0, 0};
  StopSample last_;  // at the last step's end
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

SimulateSummary run_simulation(const CompiledModel& model, const ForceModel& forces,
                               const TimeGrid& grid,
                               const std::function<void(const SimulatedRow&)>& sink,
                               const SimulateOptions& options) {
  check_input_coverage(model, grid.t0, grid.t1);
  std::unique_ptr<MotionFormulation> f = make_formulation(options.method, model, forces, grid.t0);
  Integration integration(model, forces, *f, options, grid.t0, grid.t1,
                          breakpoints(model, forces, grid.t0, grid.t1));
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
  for (int k = 1; k <= grid.steps && !integration.stopped(); ++k) {
    // The last row exactly at t1, where the integration stops.
    const double t = k == grid.steps ? grid.t1 : std::min(grid.at(k), grid.t1);
    integration.cover(t);
    if (integration.stopped() && integration.stop_time() <= t) break;
    emit(t);
  }
  if (integration.stopped() && integration.stop_time() > grid.t0) emit(integration.stop_time());
  return integration.summary();
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

SimulateOptions simulate_options(double rtol, std::optional<double> atol_given,
                                 const std::string& method, const std::string& integrator,
                                 const std::string& prefix) {
  // Below kMinRtol CVODE asks for more than double precision holds; above kMaxRtol the energy
  // balance's bound (and every figure) is meaningless. atol: below kMinAtol a state near 0
  // weighs its error beyond what rounding can meet.
  const auto range = [](double lo, double hi) {
    return "[" + format_number(lo) + ", " + format_number(hi) + "]";
  };
  if (!std::isfinite(rtol) || !(rtol >= kMinRtol && rtol <= kMaxRtol))
    throw UsageError(prefix + "rtol must be in the usable range " + range(kMinRtol, kMaxRtol) +
                     ", not " + format_number(rtol));
  const double atol = atol_given ? *atol_given : kAtolPerRtol * rtol;
  if (!std::isfinite(atol) || !(atol >= kMinAtol && atol <= kMaxAtol))
    throw UsageError(prefix + "atol must be in the usable range " + range(kMinAtol, kMaxAtol) +
                     " (times each state's scale), not " + format_number(atol));
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
