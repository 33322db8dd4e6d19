// Kinetostatics (mechanism format 6.5): driver efforts and joint reactions of a kinematically
// driven motion, from M qdd + Phi_q^T lambda = Q^A with the centre-of-mass kinematics written
// out, i.e. Phi_q^T lambda = Q with Q = Q^A + the inertia forces of the motion.
//
// Takes: the mechanism, its mass data and loads (ForceSpec), the symbol table and symbolic
// model. Gives: ForceModel (the applied generalized force Q^A(q, qd, t) as expressions, the
// bodies' mass data evaluated) and, per solved row (q, qd, qdd at t), lambda, the efforts and
// the reactions in the spec's columns, units, signs and points.
#pragma once

#include <ginac/ginac.h>

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "kinegen/codegen/mechanism.hpp"
#include "kinegen/codegen/model.hpp"
#include "kinegen/codegen/program.hpp"

namespace kinegen::codegen {

struct ForceModel {
  std::vector<GiNaC::ex> applied;  // Q^A(q, qd, t), nq: gravity and the loads
  Program applied_program;
  std::vector<double> mass, inertia;
  std::vector<Eigen::Vector2d> com;
  // Per joint and driver (in constraints() order): si and sj evaluated. A joint reports on
  // body j at sj, or on body i at si when j is ground (absolute_* keep s in si).
  std::vector<Eigen::Vector2d> si, sj;
};

// Builds Q^A and evaluates the mass data. Throws InputError for negative or non-finite mass
// data, unknown bodies, expressions that are not allowed (velocities) or not finite.
ForceModel derive_forces(const CompiledModel& model, const ForceSpec& spec);
// The same for the mechanism's own masses, gravity and loads.
inline ForceModel derive_forces(const CompiledModel& model) {
  return derive_forces(model, model.mechanism().forces);
}

// Column names added by `analyze --forces`: every driver's effort(s), then every joint's
// reaction (fx, fy, tz), in file order.
std::vector<std::string> force_columns(const Mechanism& mechanism);

// Solves Phi_q^T lambda = Q at one solved row and writes the force columns. Allocates its
// work space on construction only.
class ForceSolver {
 public:
  ForceSolver(const CompiledModel& model, const ForceModel& forces);

  // Returns false when Phi_q^T is singular (then `columns` is NaN).
  bool solve(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
             const Eigen::VectorXd& qdd, std::vector<double>& columns);

  // Q = Q^A + inertia forces at the last solve, lambda, and the scaled condition estimate of
  // Phi_q there (infinity when singular).
  const Eigen::VectorXd& generalized_force() const { return q_total_; }
  const Eigen::VectorXd& lambda() const { return lambda_; }
  double condition() const { return condition_; }
  // The generalized reaction -Phi_q^T lambda of one constraint (rows of constraints()[c]).
  Eigen::VectorXd reaction_of(int constraint) const;

 private:
  const CompiledModel* model_;
  const ForceModel* forces_;
  ModelEvaluator<double> eval_;
  ProgramEvaluator<double> applied_;
  std::vector<double> params_;
  std::vector<int> row_begin_;  // rows of each constraint: [row_begin_[c], row_begin_[c+1])
  Eigen::MatrixXd jac_;
  Eigen::VectorXd q_total_, lambda_;
  double condition_ = 0;
};

}  // namespace kinegen::codegen
