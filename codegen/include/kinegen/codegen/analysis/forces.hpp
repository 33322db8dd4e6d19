// Kinetostatics, the numeric half (docs/format.md: Force columns): driver efforts and joint
// reactions of a kinematically driven motion, from M qdd + Phi_q^T lambda = Q^A with the
// centre-of-mass kinematics written out, i.e. Phi_q^T lambda = Q with Q = Q^A + the inertia
// forces of the motion.
//
// Takes: a CompiledModel and the ForceModel of symbolic/forces.hpp (Q^A as expressions, the
// bodies' mass data evaluated). Gives: per solved row (q, qd, qdd at t), lambda, the efforts
// and the reactions in the spec's columns, units, signs and points.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/kinematics.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/codegen/program/program.hpp"
#include "kinegen/codegen/symbolic/forces.hpp"
#include "kinegen/kernels/report.hpp"

namespace kinegen::codegen {

// Adds the inertia forces of the motion to Q: -m a_com at each centre of mass (a_com with the
// omega^2 term of an offset centre) and -J alpha.
template <class T>
void add_inertia_forces(const ForceData<T>& d, int bodies, const T* q, const T* qd,
                        const T* qdd, T* out) {
  using std::cos, std::sin;
  for (int b = 0; b < bodies; ++b) {
    const T& phi = q[3 * b + 2];
    const auto p = point_kinematics(q + 3 * b, qd + 3 * b, qdd + 3 * b, T(cos(phi)),
                                    T(sin(phi)), d.com[b][0], d.com[b][1]);
    const T ax = p[0] - q[3 * b], ay = p[1] - q[3 * b + 1];  // A com
    const T fx = -d.mass[b] * p[4], fy = -d.mass[b] * p[5];
    out[3 * b] += fx;
    out[3 * b + 1] += fy;
    out[3 * b + 2] += ax * fy - ay * fx - d.inertia[b] * qdd[3 * b + 2];
  }
}

// A cam contact's J.fn: the force on body j along the unit normal of curve_i at
// the contact, the tangent t = A_i curve_i'(a) turned by -90 degrees (outward for a profile
// that runs counterclockwise), so positive in compression. t is -d(contact rows)/da, read off
// Phi_q. (fx, fy): the joint's reported force, on j, or on i when `on_j` is false.
template <class T>
T normal_force(const Mechanism& m, const ForceModel& f, int joint, const T* jac, bool on_j,
               const T& fx, const T& fy) {
  using std::sqrt;
  const int nq = m.nq(), r0 = f.row_begin[joint];
  const int a = m.coordinate_index(m.joints[joint].coordinates.at("coordinate_i"));
  const T tx = -jac[r0 * nq + a], ty = -jac[(r0 + 1) * nq + a];
  const T fjx = on_j ? fx : -fx, fjy = on_j ? fy : -fy;
  return (fjx * ty - fjy * tx) / sqrt(tx * tx + ty * ty);
}

// The columns of `analyze --forces` (force_columns order) from lambda, with Phi_q dense and
// row-major (nc x nq) at the same q.
template <class T>
void columns_from_lambda(const Mechanism& m, const ForceModel& f, const ForceData<T>& d,
                         const T* q, const std::vector<T>& jac, const std::vector<T>& lambda,
                         std::vector<T>& out) {
  using std::cos, std::sin, std::sqrt;
  const int nq = m.nq();
  const auto rotate = [&](int body, const std::array<T, 2>& s) -> std::array<T, 2> {
    if (body == kGround) return s;
    const T c = cos(q[3 * body + 2]), sn = sin(q[3 * body + 2]);
    return {c * s[0] - sn * s[1], sn * s[0] + c * s[1]};
  };
  const auto at = [&](int body, const std::array<T, 2>& s) -> std::array<T, 2> {
    const auto a = rotate(body, s);
    if (body == kGround) return a;
    return {q[3 * body] + a[0], q[3 * body + 1] + a[1]};
  };
  // -Phi_q^T lambda of constraint c, at coordinate k.
  const auto reaction = [&](int c, int k) {
    T g = T(0);
    for (int r = f.row_begin[c]; r < f.row_begin[c + 1]; ++r) g = g - jac[r * nq + k] * lambda[r];
    return g;
  };
  out.clear();
  const int nj = static_cast<int>(m.joints.size());
  for (std::size_t di = 0; di < m.drivers.size(); ++di) {
    const Constraint& c = m.drivers[di];
    if (c.free) continue;  // no actuator (force_columns)
    const int k = nj + static_cast<int>(di), r0 = f.row_begin[k];
    if (is_distance(c)) {
      // Phi = d.d - f^2: the force along d is -lambda dPhi/dL = -2 lambda L.
      const auto pj = at(c.j, d.sj[k]), pi = at(c.i, d.si[k]);
      const T dx = pj[0] - pi[0], dy = pj[1] - pi[1];
      out.push_back(T(-2) * lambda[r0] * sqrt(dx * dx + dy * dy));
    } else {
      for (int r = r0; r < f.row_begin[k + 1]; ++r) out.push_back(-lambda[r]);
    }
  }
  for (int j = 0; j < nj; ++j) {
    const Constraint& c = m.joints[j];
    if (is_expression(c)) continue;
    const bool on_j = c.j != kGround;
    const int body = on_j ? c.j : c.i;
    const T fx = reaction(j, 3 * body), fy = reaction(j, 3 * body + 1);
    const auto a = rotate(body, on_j ? d.sj[j] : d.si[j]);
    out.push_back(fx);
    out.push_back(fy);
    out.push_back(reaction(j, 3 * body + 2) - (a[0] * fy - a[1] * fx));  // about the point
    if (c.kind->normal_force) out.push_back(normal_force(m, f, j, jac.data(), on_j, fx, fy));
  }
}

// derive_forces (symbolic/forces.hpp) on the pieces a CompiledModel holds.
ForceModel derive_forces(const CompiledModel& model, const ForceSpec& spec);
// The same for the mechanism's own masses, gravity and loads: the compile stage's, derived once.
inline ForceModel derive_forces(const CompiledModel& model) { return model.forces(); }

// What `analyze --forces` needs, checked first: UsageError for a redundant model (more
// equations than coordinates), whose reactions are not unique, naming the equations that are
// redundant where it assembles at t0; derive_forces' InputErrors.
ForceModel forces_for_analysis(const CompiledModel& model, double t0 = 0);

// The singularity rule of the force solve, one for the in-process and the generated paths:
// Phi_q^T counts as singular where the reciprocal of its scaled condition estimate is at most
// the block kernels' min_rcond for the scalar (BasicBlockOptions: 2^-(3 digits / 4), double
// 1.8e-12, float 3.8e-6). The generated solve_forces applies it to each block (status 2),
// ForceSolver to the whole scaled Phi_q.
template <class R>
R force_min_rcond() {
  return kernels::ReportKernel::BasicBlockOptions<R>{}.min_rcond;
}

// Solves Phi_q^T lambda = Q at one solved row and writes the force columns. Allocates its
// work space on construction only.
class ForceSolver {
 public:
  ForceSolver(const CompiledModel& model, const ForceModel& forces,
              double min_rcond = force_min_rcond<double>());
  // applied_ points into programs_.
  ForceSolver(const ForceSolver&) = delete;
  ForceSolver& operator=(const ForceSolver&) = delete;

  // The run-time inputs' values that Q^A reads (a load's input; Mechanism::input_slots), not
  // owned; without, they are 0.
  void set_inputs(const double* inputs) { applied_.set_inputs(inputs); }

  // Returns false when Phi_q^T is singular by force_min_rcond's rule, or lambda is not finite
  // (then `columns` is NaN).
  bool solve(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
             const Eigen::VectorXd& qdd, std::vector<double>& columns);
  // Whether the last failed solve failed by the singularity rule (else by a value that is not
  // finite: a load, a weight, an inertia force, or efforts beyond a double).
  bool singular() const { return !(1 / condition_ > min_rcond_); }
  // After a failed solve that is not singular(), at the same state: what is not finite, named
  // ("the load forces[0] (torque) 'bad' (line 12) is nan here", "the weight of body 'a' (mass
  // 1e+308) overflows"); each load and each body's weight and inertia force are evaluated on
  // their own.
  std::string failure_cause(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                            const Eigen::VectorXd& qdd) const;

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
  std::shared_ptr<const ForcePrograms> programs_;  // the compile stage's Q^A
  ProgramEvaluator<double> applied_;
  std::vector<double> params_;
  Eigen::MatrixXd jac_;
  Eigen::VectorXd q_total_, lambda_;
  std::vector<double> jac_row_major_, lambda_values_;
  double condition_ = 0;
  double min_rcond_;
};

}  // namespace kinegen::codegen
