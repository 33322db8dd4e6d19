// The high-precision reference of forward dynamics (`kinegen simulate --reference D`): the
// minimal-coordinates equations of motion of analysis/dynamics.hpp in CLN arithmetic with D
// significant digits, on the symbolic expressions themselves (the HighPrecisionEvaluator of
// analysis/reference.hpp), integrated by Gragg-Bulirsch-Stoer extrapolation. What the double
// simulation (CVODE on the block program) is measured against.
//
// ReferenceDynamics: at (t, z, zd), Newton for q on [Phi of the joints and prescribed drivers;
// g_k(q) - z_k for the free items] (g: SymbolicModel::free_values), qd from Phi_q qd = nu (the
// free rows: zd), c from Phi_q c = gamma (at zdd = 0), B from Phi_q B = E, then
// (B^T M B) zdd = B^T (Q^A + the inertia forces at c), with M v as kernels/dynamics.hpp's
// _mass_times writes it, all in one dense LU of Phi_q with partial pivoting.
//
// run_reference_simulation: the modified midpoint rule with Aitken-Neville extrapolation
// (harmonic sequence 2, 4, 6, ..., up to D/3 + 4 lines, at most 60), order and step size from
// the extrapolation error (Hairer, Norsett and Wanner I, II.9), a local tolerance of
// 10^-(D-2), steps that land exactly on the grid's times, stop_when roots by the Illinois
// method on re-integrated steps, and the work integral as one more state. The arithmetic
// carries D digits plus the guard digits that the extrapolation's amplification of rounding
// takes (log10 of its Lebesgue constant + 2: 7 at D = 30). Rows are rounded to double once,
// for simulate_csv_row. Measured: D - 1 to D digits on the pendulum's half period (D = 20, 30,
// 60), D - 3 on a damped four-bar over a second. A scaled condition estimate of Phi_q above
// 1e8 fails as in double (the minimal coordinates end at singular positions). The cost grows
// quickly with D (the pendulum's half swing: 0.1 s at 30 digits, 2.7 s at 100).
#pragma once

#include <ginac/ginac.h>

#include <array>
#include <functional>
#include <memory>
#include <vector>

#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/analysis/simulate.hpp"

namespace kinegen::codegen {

// The digits `simulate --reference D` accepts: below 16 it is no reference for double, above 60
// a run's cost grows beyond any test's use (the cost per step grows like D^2 to D^3).
inline constexpr int kMinSimulateReferenceDigits = 16;
inline constexpr int kMaxSimulateReferenceDigits = 60;
// UsageError naming the range unless kMinSimulateReferenceDigits <= digits <=
// kMaxSimulateReferenceDigits: the command line checks before it writes anything, and
// run_reference_simulation_exact again for its other callers.
void check_reference_digits(int digits);
// InputError, naming stop_when's line, when it reads force columns (`-J.fn`): the reference
// has no rate for them, so nothing would bound its steps near a crossing (a brief excursion
// would be stepped over). The command line checks before it writes anything.
void check_reference_stop_when(const CompiledModel& model);

// A state of the equations of motion in high precision.
struct ReferenceMotionState {
  GiNaC::numeric t;
  std::vector<GiNaC::numeric> z, zd, zdd;  // nf
  std::vector<GiNaC::numeric> q, qd, qdd;  // nq
  std::vector<GiNaC::numeric> b;           // dq/dz, column k at b[k * nq]
  GiNaC::numeric power;  // of the loads, dampers and prescribed drivers (the work's rate)
};

class ReferenceDynamics {
 public:
  using Vector = std::vector<GiNaC::numeric>;
  // Runs the double ReducedDynamics' checks of the free items at t0 (InputError), then solves
  // the state at t0 in high precision from its position (value0 and v0 evaluated at D
  // digits). UsageError when digits is outside [kMinReferenceDigits, kMaxReferenceDigits].
  ReferenceDynamics(const CompiledModel& model, const ForceModel& forces, int digits, double t0);
  ~ReferenceDynamics();
  ReferenceDynamics(const ReferenceDynamics&) = delete;
  ReferenceDynamics& operator=(const ReferenceDynamics&) = delete;

  int nf() const { return nf_; }
  int nq() const { return nq_; }
  int digits() const;
  GiNaC::numeric to_float(const GiNaC::numeric& x) const;
  const ReferenceMotionState& initial() const { return initial_; }
  // Each free coordinate's scale (1 for angles, the length scale otherwise), as in double.
  const std::vector<double>& scales() const { return scales_; }

  // The equations of motion at (t, z, zd) into out. Newton starts from the last state
  // evaluated or given to start_from, moved along B by the change in z and along the
  // prescribed drivers' rates by the change in t. Throws AnalysisError with the reason
  // (Newton failed, a singular or ill-conditioned Phi_q, the branch left, a singular reduced
  // mass, a value not real, t outside a table).
  void evaluate(const GiNaC::numeric& t, const Vector& z, const Vector& zd,
                ReferenceMotionState& out);
  void start_from(const ReferenceMotionState& s);

  // Kinetic and potential energy at a state (the energy columns).
  std::array<GiNaC::numeric, 2> energy(const ReferenceMotionState& s);

  HighPrecisionEvaluator& evaluator();

 private:
  struct Impl;
  void solve_position(const GiNaC::numeric& t, const Vector& z, ReferenceMotionState& out);
  void check_position(const Vector& q, const Vector& predicted, const Vector& f);
  void solve_motion(ReferenceMotionState& out);

  const CompiledModel& model_;
  const ForceModel& forces_;
  int nq_ = 0, nf_ = 0;
  std::unique_ptr<Impl> impl_;
  std::vector<double> scales_;
  ReferenceMotionState initial_;
};

// A simulated row in high precision: the kinematics (t, q, qd, qdd, points, outputs), the
// free coordinates, the energy terms and, with SimulateOptions::forces_columns, the force
// columns.
struct ReferenceSimulatedRow {
  ReferenceRow row;
  std::vector<GiNaC::numeric> z, zd, zdd;
  GiNaC::numeric kinetic, potential, work, balance;
  std::vector<GiNaC::numeric> forces;
};

// The row rounded to double (each value once, to nearest), for simulate_csv_row.
SimulatedRow to_simulated_row(const ReferenceSimulatedRow& row);

// What the integrator did, for reports and tests.
struct ReferenceSimulationStats {
  long steps = 0, rejected = 0, evaluations = 0;
  int largest_column = 0;  // of the extrapolation tableau (order 2 * column)
  // A stop_when crossing (or stop_when > 0 at t0) ended the run at stop_time; stop_bound as
  // SimulateSummary's.
  bool stopped = false;
  double stop_time = 0, stop_bound = 0;
};

// Integrates over the grid like run_simulation (rows at the grid's times, one at a stop_when
// root where the run ends; options: forces_columns, progress, interrupted, max_steps; rtol,
// atol, integrator and method do not apply). Every step ends at each breakpoint
// (analysis/breakpoints.hpp), those of the state located to the root tolerance. Throws
// AnalysisError after the rows so far, also when interrupted (interruption_point(), checked at
// every evaluation: "FILE: interrupted at t = T"); UsageError for digits outside
// [kMinSimulateReferenceDigits, kMaxSimulateReferenceDigits] or too many breakpoints.
ReferenceSimulationStats run_reference_simulation_exact(
    const CompiledModel& model, const ForceModel& forces, const TimeGrid& grid, int digits,
    const std::function<void(const ReferenceSimulatedRow&)>& sink,
    const SimulateOptions& options = {});
ReferenceSimulationStats run_reference_simulation(
    const CompiledModel& model, const ForceModel& forces, const TimeGrid& grid, int digits,
    const std::function<void(const SimulatedRow&)>& sink, const SimulateOptions& options = {});

}  // namespace kinegen::codegen
