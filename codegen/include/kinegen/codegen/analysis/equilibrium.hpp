// Equilibrium and small oscillations (docs/format.md, Equilibrium and small oscillations), on
// the exact tangent (analysis/tangent.hpp): where the overdamped release from value0 comes to
// rest (the flow M_z dz/ds = B^T Q^A(z) followed to its rest, then polished by Newton), or
// Newton's nearest root of B^T Q^A(z) = 0 (zdd(z, zd = 0) = 0); the reduced mass, stiffness
// and damping there, M_z = B^T M B, K_z = -M_z d(zdd)/dz, C_z = -M_z d(zdd)/dzd; whether the
// equilibrium is stable (K_z positive definite), unstable (the directions it leaves along) or
// neutral (a direction of zero stiffness, as a free wheel's); the natural frequencies and
// mode shapes (dq of every coordinate), damped ones with their damping ratios.
//
// Takes: a Linearizer. Gives: Equilibrium, ModalAnalysis; AnalysisError when there is no
// equilibrium from value0.
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/tangent.hpp"

namespace kinegen::codegen {

enum class Stability { kStable, kUnstable, kNeutral };
const char* to_string(Stability s);

// The reduced mass, stiffness and damping at a state, and what K_z says about it.
struct ReducedStiffness {
  Eigen::MatrixXd mass, stiffness, damping;  // M_z, K_z, C_z (nf x nf)
  // K_z v = lambda M_z v for K_z's symmetric part: lambda (omega^2 where positive), ascending,
  // and v in z, each scaled to a largest component of 1 (positive).
  Eigen::VectorXd eigenvalues;
  Eigen::MatrixXd directions;
  std::vector<Stability> kinds;  // per eigenvalue: positive, negative or zero stiffness
  Stability stability = Stability::kStable;
  // The directions of negative and of zero stiffness, each described by the free coordinates
  // ("theta", or "0.707 theta - 0.707 phi").
  std::vector<std::string> unstable, neutral;
  bool symmetric = true;  // K_z symmetric to rounding (else loads that are not conservative)
};

// At a solved state (zd = 0 for K_z to be the stiffness): M_z, K_z, C_z from the Jacobians and
// the verdict. An eigenvalue counts as zero below 1e-9 of the largest, or of the forces' size
// (Linearizer::force_terms) per unit of reduced mass and scale.
ReducedStiffness reduced_stiffness(const Linearizer& linearizer, const MotionState& state,
                                   const Eigen::MatrixXd& d_z, const Eigen::MatrixXd& d_zd);

struct Equilibrium {
  OperatingPoint at;  // z found; zd = 0
  MotionState state;
  ReducedStiffness stiffness;
  Eigen::VectorXd force;    // B^T Q^A at z (with the inertia of prescribed motion): ~0
  Eigen::VectorXd bound;    // rest_bound there: |force| <= bound componentwise
  int iterations = 0;       // Newton's steps
  int flow_steps = 0;       // the release's accepted steps (0 for kNearest)
  bool left_start = false;  // the start was an equilibrium that is not stable: left along
                            // its most unstable direction
};

// How find_equilibrium searches.
enum class EquilibriumSearch {
  kRest,     // where the overdamped release from the start comes to rest
  kNearest,  // the root Newton reaches from the start, whatever its stability
};

// The largest |B^T Q^A| that is zero to rounding, per free coordinate, at a state the
// Linearizer solved last with its Jacobians, M_z and K_z there: 16 nq eps (|B|^T |Q^A| +
// |K_z| max(|z|, scale) + |M_z| |zdd|), the rounding of its own terms, of z itself (no double z
// puts a pendulum's cos z below 6e-17) and of B^T Q^A's evaluation as M_z zdd. Newton stops
// only within it, and `modes --at` calls a point an equilibrium within it.
Eigen::VectorXd rest_bound(const Linearizer& linearizer, const MotionState& state,
                           const Eigen::MatrixXd& mass, const Eigen::MatrixXd& stiffness);

// kNearest: Newton from `start` (its z; zd is taken as 0), each step the exact one on
// zdd(z) = 0 within a trust region (1 rad or the length scale, shrunk on a step that does not
// lower |zdd|); where K_z cannot place a step inside it (a singular or small stiffness: a
// pendulum at horizontal), the step follows zdd for as long as the forces pull along it. It
// stops only when |B^T Q^A| <= rest_bound.
// kRest: the flow dz/ds = zdd(z, zd = 0), i.e. M_z dz/ds = B^T Q^A, from `start` by a
// linearly implicit Euler method (exact Jacobian; step doubling for the error, a step limit
// on the flow's unstable directions), until K_z has no negative eigenvalue and Newton's step
// is below 1e-3 (rad or length scales), then Newton as above. A start that is an equilibrium
// but not stable is first moved 1e-6 along the eigenvector of the most negative eigenvalue of
// M_z^-1 K_z (its largest component positive). The flow fails after kFlowSteps steps or
// kFlowTravel scales from the start (it does not settle), or where the position does not
// solve (it leaves the assembly range or meets a singular position).
// AnalysisError, naming where it ended and the forces left there, when it finds no
// equilibrium (in max_iterations Newton steps).
inline constexpr int kFlowSteps = 20000;
inline constexpr double kFlowTravel = 1000;
Equilibrium find_equilibrium(Linearizer& linearizer, OperatingPoint start,
                             EquilibriumSearch search = EquilibriumSearch::kRest,
                             int max_iterations = 100);

struct Mode {
  double frequency = 0;         // Hz, undamped natural frequency sqrt(lambda)/(2 pi); 0 if none
  double damped_frequency = 0;  // Hz, of the damped oscillation (= frequency without damping)
  double damping_ratio = 0;     // 0 without damping; 1 or more: it does not oscillate
  double eigenvalue = 0;        // lambda (undamped); damped: |s|^2 of a pair, s of a real root
  Stability kind = Stability::kStable;  // unstable: it grows; neutral: zero stiffness
  Eigen::VectorXd dz, dq;               // the shape: largest |dz| 1; dq = B dz
};

struct ModalAnalysis {
  OperatingPoint at;
  MotionState state;
  ReducedStiffness stiffness;
  Eigen::VectorXd force;  // B^T Q^A at the point (not ~0: not an equilibrium)
  bool damped = false;    // C_z != 0: the modes are those of the state matrix
  // From the modes: unstable if one grows (a negative stiffness, or a negative damping),
  // else neutral if one has zero stiffness, else stable.
  Stability stability = Stability::kStable;
  std::vector<Mode> modes;  // ascending frequency
};

// The modes at p (zd taken as 0): of K_z v = lambda M_z v, or with damping of the state
// matrix [0 I; -M_z^-1 K_z -M_z^-1 C_z]. AnalysisError when the state does not solve there.
ModalAnalysis modal_analysis(Linearizer& linearizer, OperatingPoint p);

}  // namespace kinegen::codegen
