// Forward dynamics in minimal coordinates (docs/format.md: Equations of motion), in-process:
// the free items are input drivers whose values are the state z. At (t, z, zd) the block
// program solves q(z, t), qd = B zd + b and c, the acceleration at zdd = 0; B = dq/dz comes
// from Phi_q B = E (E: the free rows' unit vectors) with one factorization of Phi_q; then the
// dynamics kernel (kernels/dynamics.hpp) solves (B^T M B) zdd = B^T (Q^A - M c - ...) and
// qdd = c + B zdd. Nothing drifts: q is solved from z at every evaluation.
//
// Takes: a CompiledModel with free items and the ForceModel of symbolic/forces.hpp. Gives:
// the state at t0 (checked as docs/format.md's `free` requires), zdd and the full q, qd, qdd
// at any (t, z, zd), the energy terms of `simulate`, and failures with their reason.
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/symbolic/forces.hpp"

namespace kinegen::codegen {

class BlockInterpreter;

// The minimal method's two judgements of a solved position, one pair for the double
// integration (dynamics.cpp) and the high-precision reference (reference_dynamics.cpp): a
// scaled Phi_q whose condition estimate exceeds kSingularCondition is a singular position (as
// in `analyze`: cond * eps would reach 1e-8), and a solution that misses the first-order
// prediction from the last one by more than kBranchJumpFraction of the predicted change
// (scaled) left its branch.
inline constexpr double kSingularCondition = 1e8;
inline constexpr double kBranchJumpFraction = 0.25;

// Why an evaluation of the equations of motion failed.
enum class MotionFailure {
  kNone,
  kPosition,      // q(z, t) not found: Newton failed, or a singular or ill-conditioned Phi_q
  kBranch,        // the solution left its assembly branch (a singular position was crossed)
  kReducedMass,   // B^T M B is singular: a free coordinate moves no mass here
  kNonFinite,     // a value is NaN or infinite (a load, a table)
  kOutsideTable,  // t lies outside a table's range
};

struct MotionState {
  double t = 0;
  Eigen::VectorXd z, zd, zdd;  // nf
  Eigen::VectorXd q, qd, qdd;  // nq
};

// The energy terms of `simulate` at one state.
struct Energy {
  double kinetic = 0;    // 1/2 qd^T M qd
  double potential = 0;  // gravity and springs (preloads included)
  double power = 0;      // of the loads, dampers and prescribed drivers: the work's rate
};

// The energy that `simulate`'s absolute tolerance on the work (and its reference's) is a
// fraction of: kinetic + |potential| at t0, or where the start holds less, the model's own unit
// 1/2 sum(m L^2 + I) per second squared (each body moving at one length scale L and turning at
// one radian per second). Not a fixed 1 J, which held a gram-sized mechanism's balance to a
// bound a hundred times its energy.
inline double energy_scale(double start_energy, const ForceModel& forces, double length_scale) {
  double unit = 0;
  const ForceData<double>& d = forces.numbers;
  for (std::size_t b = 0; b < d.mass.size(); ++b)
    unit += 0.5 * (d.mass[b] * length_scale * length_scale + d.inertia[b]);
  const double scale = std::max(std::abs(start_energy), unit);
  // No mass at all never integrates (the reduced mass is singular); 1 keeps the tolerance
  // positive for the message that says so.
  return scale > 0 ? scale : 1.0;
}

class ReducedDynamics {
 public:
  // Checks at t0 what docs/format.md asks of free items (`free`) and assembles there: the
  // counts (naming the degrees of freedom), the rank with the free items (naming the item that
  // adds nothing), value0 (InputError when the mechanism does not assemble there), the reduced
  // mass (naming a free item that moves no mass). The model and forces must outlive it.
  ReducedDynamics(const CompiledModel& model, const ForceModel& forces, double t0);
  ~ReducedDynamics();
  ReducedDynamics(const ReducedDynamics&) = delete;
  ReducedDynamics& operator=(const ReducedDynamics&) = delete;

  int nf() const { return nf_; }
  int nq() const { return nq_; }
  // z and zd at t0 (value0 and v0, or their defaults), and the state there.
  const MotionState& initial() const { return initial_; }

  // The equations of motion at (t, z, zd): true and the state (zdd, q, qd, qdd) on success;
  // false and failure() / reason() otherwise. Starts Newton from the last solution, moved
  // along B by the change in z, so that it stays on the branch it assembled on.
  bool evaluate(double t, const double* z, const double* zd, MotionState& out);
  // An evaluation between keep() and restore() leaves no trace in the next one (Newton's
  // start, the branch check's reference, the block solver's sin/cos cache and signs): a row or
  // a stop_when sample between the integrator's steps, so that the steps, and so the rows, do
  // not depend on the output grid.
  void keep();
  void restore();
  MotionFailure failure() const { return failure_; }
  // One line: what failed.
  const std::string& reason() const { return reason_; }

  // The energy terms at a state evaluate() returned (the power needs its qdd, for the
  // prescribed drivers' efforts).
  Energy energy(const MotionState& s);

  // Why the integrator could not go on from (t, z, zd), where it failed with no failed
  // evaluation (its error test, near a singular position): the singular position's reason
  // when q is not found there or Phi_q's condition estimate is 1000 times its value at t0,
  // else empty.
  std::string singular_diagnosis(double t, const double* z, const double* zd);

  // dq/dz at the last successful evaluation (nq x nf).
  const Eigen::MatrixXd& b() const { return b_; }

  // The run-time inputs' values (Mechanism::input_slots: 3 per driver, then the loads'
  // inputs), which the programs read: set an input driver's or a load's here (run_inputs
  // names them); the free items' slots are the state, written by each evaluation. 0 until set.
  double* input_slots();

 private:
  struct Impl;
  bool solve(double t, const double* z, const double* zd, MotionState& out);
  void check_at_t0(double t0);
  Eigen::VectorXd assemble_fixed(double t0, const std::vector<int>& fixed_rows);
  void check_counts_and_rank(double t0, const Eigen::VectorXd& q,
                             const std::vector<int>& fixed_rows);
  [[noreturn]] void report_t0_failure(double t0);
  bool solve_kinematics(double t, MotionState& out, double& condition);
  bool reduce(double t, MotionState& out);
  bool fail(MotionFailure f, std::string reason);
  bool singular_failure(double t, const MotionState& out, bool branch, int block,
                        const std::string& detail = "");
  std::string singular_reason(double t, const MotionState& out, bool branch, int block,
                              const std::string& detail);

  const CompiledModel& model_;
  const ForceModel& forces_;
  int nq_ = 0, nf_ = 0;
  std::vector<int> free_rows_;  // the row of Phi of each free item
  std::unique_ptr<Impl> impl_;
  MotionState initial_;
  Eigen::MatrixXd b_;
  MotionFailure failure_ = MotionFailure::kNone;
  std::string reason_;
  double condition_ = 1, condition0_ = 1;  // Phi_q's, at the last solve and at t0
};

// The free items' names (their CSV columns Z, Z.v, Z.a), in `free:` order.
std::vector<std::string> free_names(const Mechanism& m);

}  // namespace kinegen::codegen
