// Forward dynamics through singular positions (`simulate --method augmented`): the
// index-1 augmented Lagrangian formulation (ALF) of
//   E. Bayo, J. Garcia de Jalon, M. A. Serna, "A modified Lagrangian formulation for the dynamic
//   analysis of constrained mechanical systems", Computer Methods in Applied Mechanics and
//   Engineering 71 (1988) 183-195, and J. Garcia de Jalon, E. Bayo, "Kinematic and Dynamic
//   Simulation of Multibody Systems: The Real-Time Challenge", Springer 1994, chapter 5,
// with the mass-orthogonal projections of positions and velocities after each step of
//   E. Bayo, R. Ledesma, "Augmented Lagrangian and mass-orthogonal projection methods for
//   constrained multibody dynamics", Nonlinear Dynamics 9 (1996) 113-130.
//
// The state is y = [q, qd] in all coordinates. The constraints are the joints and the
// prescribed drivers only: the free items are not constraints here, they only name the
// columns Z, Z.v, Z.a, read off q, qd and qdd. At each evaluation
//   (M + Phi_q^T alpha Phi_q) qdd = Q - Phi_q^T alpha (Phi_q_dot qd + Phi_t_dot + 2 xi omega
//                                   Phi_dot + omega^2 Phi) - Phi_q^T lambda*,
//   lambda*_{i+1} = lambda*_i + alpha (Phi_ddot + 2 xi omega Phi_dot + omega^2 Phi)_{i+1},
// iterated (in the residual form of iterative refinement, so that the penalty's conditioning
// costs no accuracy) until qdd stops changing, from lambda*_0 = the multipliers at the last
// step's projected state, as the literature starts it, held for all the evaluations of a step
// so that they are one smooth function of y. M + Phi_q^T alpha Phi_q stays positive definite
// where Phi_q loses rank, so the iteration passes a singular position: there it converges
// slowly in the directions that became free for an instant, whose constraint residual
// vanishes with the rank. After each step CVODE (BDF, CVodeSetProjFn) calls project(): the
// mass-orthogonal projections min |q - q*|_M with Phi(q) = 0 and min |qd - qd*|_M with
// Phi_q qd = nu, solved by the same augmented Lagrangian iteration on the same matrix (Bayo
// and Ledesma's projections, iterated to convergence); project_error() projects CVODE's local
// error estimate alike, so that the error test judges the projected solution.
//
// Takes: a CompiledModel with free items, its ForceModel, t0. Gives: a MotionFormulation for
// run_simulation (analysis/simulate.hpp). The start (q, qd at t0) is the minimal method's, so
// the free items' checks at t0 (docs/format.md: `free`) hold for both methods alike.
#pragma once

#include <memory>

#include "kinegen/codegen/analysis/simulate.hpp"

namespace kinegen::codegen {

// The method's constants, scaled to the model at t0:
// - alpha: one penalty per constraint row, alpha_r = penalty / max_k (Phi_q[r, k]^2 / M_kk)
//   (M_kk of a massless coordinate: the heaviest of its kind's), so that alpha Phi_q^T Phi_q
//   outweighs M by `penalty` on the coordinates each row moves, in any units. The literature
//   (Bayo, Garcia de Jalon and Serna; Garcia de Jalon and Bayo 1994) takes alpha = 1e7..1e9
//   for masses of a kilogram: there the penalized matrix is solved for qdd itself, and a
//   larger alpha costs its digits. In the residual form here it costs none while the
//   factorization keeps a few (eps * cond ~ eps * 4 penalty = 1e-3), so the penalty is
//   larger: the window around a singular position where the vanishing directions go
//   unenforced is ~ 1 / sqrt(penalty) wide, and the modes that become free there are excited
//   the less. Measured on the N = 40 four-bar at --rtol 1e-13: penalty 1e8 and 1e10 fail
//   after a flat position (the excited modes, removed by the projections just after it,
//   exhaust the error test), 1e11 to 1e13 pass.
// - xi = 1: critically damped constraint errors (the literature's).
// - omega = pi / tau, tau the model's time scale at t0: 1 / max(sqrt(|qdd_k| / s_k),
//   |qd_k| / s_k) over the coordinates (s_k their scales), 1 s at rest without loads. For a
//   metre under gravity tau = sqrt(1 m / 9.81 m s^-2) and omega = 9.8 s^-1, the literature's
//   10 s^-1.
struct AugmentedSettings {
  double penalty = 1e12;
  double xi = 1.0;
  double omega = 0;          // 0: pi / tau
  int max_iterations = 100;  // of the lambda* iteration per evaluation (it converges in 2 to 4
                             // off singular positions)
};

std::unique_ptr<MotionFormulation> augmented_formulation(const CompiledModel& model,
                                                         const ForceModel& forces, double t0,
                                                         const AugmentedSettings& settings);

}  // namespace kinegen::codegen
