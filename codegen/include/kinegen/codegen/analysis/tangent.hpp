// The tangent of the minimal-coordinates dynamics, in-process: at a state ReducedDynamics
// solved, the exact d(zdd)/dz, d(zdd)/dzd and d(zdd)/du. The symbolic stage's derivatives
// (symbolic/tangent.hpp) are lowered to one program; the dynamics tangent kernel
// (kernels/linearize.hpp), which generated headers carry too, combines them with solves on
// Phi_q through its blocks by the block_linear kernel, as generated code solves (or, where the
// blocks do not serve, on one LU of Phi_q).
//
// Takes: a CompiledModel with free items and its ForceModel. Gives: Linearizer, which solves
// the state at an operating point (t, z, zd, u) and the Jacobians there.
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/dynamics.hpp"

namespace kinegen::codegen {

// Where the dynamics is evaluated: t, the free coordinates' z and zd (Mechanism::free_drivers
// order) and the run-time inputs u (run_inputs order).
struct OperatingPoint {
  double t = 0;
  Eigen::VectorXd z, zd, u;
};

class Linearizer {
 public:
  // ReducedDynamics' checks at t0 (docs/format.md: `free`) apply. model and forces must
  // outlive it. blocks: solve through Phi_q's blocks where they serve (false: always on one LU
  // of all of Phi_q, a cross-check as `analyze --solver dense` is).
  Linearizer(const CompiledModel& model, const ForceModel& forces, double t0, bool blocks = true);
  ~Linearizer();
  Linearizer(const Linearizer&) = delete;
  Linearizer& operator=(const Linearizer&) = delete;

  ReducedDynamics& dynamics() { return dynamics_; }
  const CompiledModel& model() const { return model_; }
  const ForceModel& forces() const { return forces_; }
  int nf() const { return dynamics_.nf(); }
  int nu() const { return static_cast<int>(inputs_.size()); }
  // The state at t0 with u = 0.
  OperatingPoint initial() const;

  // Solves the state at p (q, qd, qdd, zdd; reached from the last point solved by
  // continuation where it is far from it); with d_z, d_zd, d_u not null also the Jacobians
  // d(zdd)/dz, d(zdd)/dzd (nf x nf) and d(zdd)/du (nf x nu). false and reason() when the
  // state does not solve or a solve of the tangent fails.
  bool evaluate(const OperatingPoint& p, MotionState& state, Eigen::MatrixXd* d_z = nullptr,
                Eigen::MatrixXd* d_zd = nullptr, Eigen::MatrixXd* d_u = nullptr);
  const std::string& reason() const { return reason_; }

  // M_z = B^T M B at the state evaluate() solved last (s).
  Eigen::MatrixXd reduced_mass(const MotionState& s) const;
  // Each free coordinate's scale: 1 for an angle, the mechanism's length scale for a length.
  Eigen::VectorXd scales() const;
  // |B|^T |Q^A| at the state of the last Jacobians: the size of the generalized forces on the
  // free coordinates, against which a stiffness counts as zero.
  const Eigen::VectorXd& force_terms() const { return force_terms_; }

 private:
  struct Impl;
  bool solve_at(const OperatingPoint& p, MotionState& state);
  bool solve_state(const OperatingPoint& p, MotionState& state);
  bool tangent(const MotionState& s, const std::vector<int>& slots, Eigen::MatrixXd& out);

  const CompiledModel& model_;
  const ForceModel& forces_;
  ReducedDynamics dynamics_;
  std::vector<RunInput> inputs_;
  std::unique_ptr<Impl> impl_;
  OperatingPoint last_;  // the last point solved, where a walk to the next starts
  std::string reason_;
  Eigen::VectorXd force_terms_;
};

}  // namespace kinegen::codegen
