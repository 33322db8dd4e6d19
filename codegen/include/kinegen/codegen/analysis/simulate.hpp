// Forward dynamics over a time grid: a formulation of the equations of motion as
// an ODE, integrated by SUNDIALS CVODE (BDF or Adams, its error control, its dense
// output on the grid, its root finding for stop_when), with the energy columns.
//
// Takes: a CompiledModel with free items, its ForceModel, the grid and options. Gives: rows
// (StateRow with the free coordinates and the energy terms) to a sink as they are computed;
// an AnalysisError naming the time and the cause when the run fails, after the rows so far.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/dynamics.hpp"

namespace kinegen::codegen {

// The equations of motion as y' = f(t, y) for the integrator: minimal coordinates
// (y = [z, zd]) or a formulation in all of q (the augmented Lagrangian, y = [q, qd]).
class MotionFormulation {
 public:
  virtual ~MotionFormulation() = default;
  virtual int size() const = 0;
  // y at t0, and each entry's scale (atol is --atol times it).
  virtual Eigen::VectorXd initial() const = 0;
  virtual Eigen::VectorXd scales() const = 0;
  // y' at (t, y); on success state() is the full state there. false: failure() says why
  // (the integrator may retry with a smaller step).
  virtual bool rhs(double t, const double* y, double* ydot) = 0;
  virtual const MotionState& state() const = 0;
  virtual Energy energy() = 0;  // at state()
  // The sum of |power| over the loads, dampers, prescribed drivers and the potential's forces
  // at state() (per coordinate; e its energy()): the rate of the energy exchanged, X' in the
  // energy balance's bound.
  virtual double activity(const Energy& e) = 0;
  // An evaluation between keep() and restore() (a row, a stop_when sample) leaves no trace in
  // the next rhs: the steps, and so the rows, do not depend on the output grid. Nothing to keep
  // by default (an rhs that is a function of (t, y) alone).
  virtual void keep() {}
  virtual void restore() {}
  virtual MotionFailure failure() const = 0;
  virtual const std::string& reason() const = 0;
  // Projection onto the constraints after each step (CVODE's CVodeSetProjFn): the
  // correction that brings y back to Phi = 0 and Phi_q qd = nu. None by default.
  virtual bool has_projection() const { return false; }
  virtual bool project(double /*t*/, const double* /*y*/, double* /*correction*/) {
    return true;
  }
  // Called right after project() with CVODE's local error estimate (size()), which it may
  // project in place: the components the projection removes are no error of the projected
  // solution. As it is by default.
  virtual bool project_error(double /*t*/, double* /*error*/) { return true; }
  // What advice a failure gets (the other method, for the minimal coordinates).
  virtual std::string advice() const { return ""; }
  // The cause, with its advice, when the integrator gave up at (t, y) with no evaluation
  // failing there (its error test, near a singular position); empty when the formulation
  // knows none.
  virtual std::string diagnose(double /*t*/, const double* /*y*/) { return ""; }
};

// The default method: minimal coordinates on ReducedDynamics.
std::unique_ptr<MotionFormulation> minimal_formulation(const CompiledModel& model,
                                                       const ForceModel& forces, double t0);

enum class Integrator { kAuto, kBdf, kAdams };
enum class Method { kMinimal, kAugmented };

// The usable tolerances (docs/dynamics.md): outside, simulate_options() is a UsageError.
inline constexpr double kMinRtol = 1e-14, kMaxRtol = 1e-2;
inline constexpr double kMinAtol = 1e-18, kMaxAtol = 1e-2;
// --atol when not given: this times --rtol.
inline constexpr double kAtolPerRtol = 1e-2;

struct SimulateOptions {
  double rtol = 1e-8;
  double atol = 1e-10;  // times each state's scale
  Integrator integrator = Integrator::kAuto;  // auto: BDF with springs or dampers, else Adams
  Method method = Method::kMinimal;
  // Adds the force columns (force_columns order: prescribed drivers' efforts, reactions).
  const ForceModel* forces_columns = nullptr;
  // Called with the time of each row written; and polled during the run: true stops it
  // (an interrupt), as a failure with the rows so far kept.
  std::function<void(double)> progress;
  std::function<bool()> interrupted;
  long max_steps = 10000000;  // internal steps in all
  // The energy balance past its bound is a warning (once, at the end), not a failure.
  bool allow_drift = false;
  double max_step = 0;  // the integrator's largest step; 0: none
};

// What a run did (`simulate -v`), and what it warns about.
struct SimulateSummary {
  std::string integrator;  // "BDF" or "Adams", and why when auto chose
  long steps = 0, evaluations = 0, error_test_failures = 0;
  long restarts = 0;  // at breakpoints, where a driver's or a load's function is not smooth
  // The largest |energy.balance| at the internal steps, its time, and its ratio to the bound's
  // tolerance term C (rtol + atol/S) (S + X) there.
  double largest_balance = 0, largest_balance_time = 0, largest_ratio = 0;
  // With allow_drift: the balance passed its bound (the largest excess, its time, the limit).
  bool drifted = false;
  std::string drift;
  // A stop_when crossing ended the run at stop_time; stop_bound: 0 when EXPR crossed 0, else
  // its error bound at t0 that EXPR rose past (StopWhenLevel).
  bool stopped = false;
  double stop_time = 0, stop_bound = 0;
};

// stop_when's error bound E (docs/format.md, Simulation): rtol times its scale g_scale (the
// largest |EXPR| so far) plus each coordinate's and rate's atol share, |dEXPR/dq_k| and
// |dEXPR/dqd_k| (by_q, by_qd: one per coordinate, or null where they are not known) times
// atol times the coordinate's scale. A value within E of 0 at t0 is no crossing: CVODE's runs
// and the reference judge t0 by this one rule.
inline double stop_when_bound(double g_scale, const double* by_q, const double* by_qd,
                              const std::vector<double>& scales, const SimulateOptions& options) {
  double bound = options.rtol * g_scale;
  for (std::size_t k = 0; by_q && by_qd && k < scales.size(); ++k)
    bound += (std::abs(by_q[k]) + std::abs(by_qd[k])) * options.atol * scales[k];
  return bound;
}

// stop_when's rule at and after t0 (docs/format.md, stop_when), one for CVODE's runs and the
// reference: g0 and E0 are EXPR and its error bound at t0. Above E0 the run stops at t0. A g0
// in (0, E0] may be a zero (no crossing) or above 0 (a stop): the run stops once EXPR exceeds
// E0 (then it was never below 0), unless EXPR goes below 0 first; otherwise at the first
// crossing of 0 from below.
class StopWhenLevel {
 public:
  StopWhenLevel(double g0, double bound0)
      : at_t0_(g0 > bound0),
        bound0_(bound0),
        level_(g0 > 0 && !at_t0_ ? std::nextafter(bound0, HUGE_VAL) : 0) {}
  bool stops_at_t0() const { return at_t0_; }
  // The run stops where EXPR passes from below level() to level() or above.
  double level() const { return level_; }
  // 0 while the level is 0, else E0: for the message saying what EXPR crossed.
  double bound() const { return level_ > 0 ? bound0_ : 0; }
  // EXPR seen along the run, below 0 or not: once below 0, the level is 0.
  void see(bool below_0) {
    if (below_0) level_ = 0;
  }

 private:
  bool at_t0_;
  double bound0_, level_;
};

// SimulateOptions from the settings as a user names them (the command line's --rtol, --atol,
// --method, --integrator with prefix "--"; the Python module's keywords with ""), each checked:
// a UsageError naming the setting and its value. One rule for both front ends.
// atol empty: kAtolPerRtol times rtol.
SimulateOptions simulate_options(double rtol, std::optional<double> atol, const std::string& method,
                                 const std::string& integrator, const std::string& prefix);

// The extra columns of a simulated row: each free item's Z, Z.v, Z.a, then the energy.
struct SimulatedRow {
  StateRow state;
  Eigen::VectorXd z, zd, zdd;
  double kinetic = 0, potential = 0, work = 0, balance = 0;
};

// The method for singular positions: an index-3 augmented Lagrangian in all of q with
// mass-orthogonal projections (analysis/augmented.cpp).
std::unique_ptr<MotionFormulation> augmented_formulation(const CompiledModel& model,
                                                         const ForceModel& forces, double t0);

// A formulation for `method`.
std::unique_ptr<MotionFormulation> make_formulation(Method method, const CompiledModel& model,
                                                    const ForceModel& forces, double t0);

// Integrates over the grid (rows at its times, and one at a stop_when root, where the run
// ends). Throws AnalysisError on failure, after the rows so far; InputError for the checks of
// the free items at t0.
SimulateSummary run_simulation(const CompiledModel& model, const ForceModel& forces,
                               const TimeGrid& grid,
                               const std::function<void(const SimulatedRow&)>& sink,
                               const SimulateOptions& options);

// The CSV header of `simulate`: analyze's columns (with the force columns when given), then
// Z, Z.v, Z.a per free item, then energy.kinetic, energy.potential, energy.work and
// energy.balance; and a row.
std::string simulate_csv_header(const Mechanism& m, const std::vector<std::string>& forces);
std::string simulate_csv_row(const SimulatedRow& row, int num_bodies);

}  // namespace kinegen::codegen
