// kinegen runtime: position, velocity and acceleration analysis of a planar mechanism.
//
// Header-only; needs Eigen and the standard library. The algorithms are written once, on a
// "system" that evaluates Phi, Phi_q, nu and gamma, and a workspace whose sizes are either
// fixed at compile time (generated models: nothing is allocated after construction) or set at
// run time (the command line's in-process models).
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

namespace kinegen {

// Why a solve stopped.
enum class Status {
  kConverged,      // success
  kMaxIterations,  // Newton did not converge within the iteration budget
  kSingular,       // Phi_q is singular or nearly so at the current configuration
  kNonFinite,      // a residual, Jacobian or step contained NaN or infinity
};

inline const char* to_string(Status s) {
  switch (s) {
    case Status::kConverged: return "converged";
    case Status::kMaxIterations: return "Newton iteration did not converge";
    case Status::kSingular: return "the constraint Jacobian Phi_q is singular";
    case Status::kNonFinite: return "a non-finite value (NaN or infinity) appeared";
  }
  return "unknown";
}

// The outcome of a solve: true on success, and why not otherwise.
struct Result {
  Status status = Status::kConverged;
  int iterations = 0;   // Newton iterations taken (position only)
  double step = 0;      // the last scaled Newton step (position only)
  double pivot_ratio = 1;  // smallest / largest |pivot| of the last factorization

  explicit operator bool() const { return status == Status::kConverged; }
  const char* message() const { return to_string(status); }
};

struct SolverOptions {
  // Newton stops when the step, with lengths divided by the model's length scale and angles
  // in radians, is at most this. Convergence is quadratic, so the position is then accurate
  // to far below it.
  double tolerance = 1e-10;
  int max_iterations = 30;
  // Phi_q counts as singular when its smallest LU pivot is below this times its largest.
  double singular_pivot_ratio = 1e-13;
  // Block solver (block_solver.hpp) only: when positive, exactly this many Newton iterations
  // per block and no convergence test, for a fixed cost per step (real-time use).
  int fixed_iterations = 0;
};

namespace detail {

// Storage for one analysis: Phi_q, its factorization and the vectors around it.
template <class Scalar, int NQ, int NC>
struct Workspace {
  using Jacobian = Eigen::Matrix<Scalar, NC, NQ>;
  using Square = Eigen::Matrix<Scalar, NQ, NQ>;
  using VectorQ = Eigen::Matrix<Scalar, NQ, 1>;
  using VectorC = Eigen::Matrix<Scalar, NC, 1>;

  explicit Workspace(int nq = NQ, int nc = NC)
      : jac(Jacobian::Zero(nc, nq)), rhs(nc), dq(nq), q_factored(nq), lu(nq) {}

  Jacobian jac;
  VectorC rhs;
  VectorQ dq;
  VectorQ q_factored;  // where the factorization was computed
  Scalar t_factored = Scalar(0);
  bool factored = false;
  Eigen::PartialPivLU<Square> lu;
};

template <class Derived>
bool all_finite(const Eigen::MatrixBase<Derived>& v) {
  return v.allFinite();
}

// Evaluates Phi_q at (q, t) and factors it. Fills `result` on failure.
template <class System, class WS, class VQ>
bool factor(const System& sys, WS& ws, const VQ& q, typename System::Scalar t,
            const SolverOptions& options, Result& result) {
  sys.jacobian(q.data(), t, ws.jac);
  ws.factored = false;
  if (!all_finite(ws.jac)) {
    result.status = Status::kNonFinite;
    return false;
  }
  ws.lu.compute(ws.jac);
  const auto diag = ws.lu.matrixLU().diagonal().cwiseAbs();
  const double largest = static_cast<double>(diag.maxCoeff());
  const double smallest = static_cast<double>(diag.minCoeff());
  result.pivot_ratio = largest > 0 ? smallest / largest : 0.0;
  if (!(result.pivot_ratio > options.singular_pivot_ratio)) {
    result.status = Status::kSingular;
    return false;
  }
  ws.q_factored = q;
  ws.t_factored = t;
  ws.factored = true;
  return true;
}

template <class System, class WS, class VQ>
bool ensure_factored(const System& sys, WS& ws, const VQ& q, typename System::Scalar t,
                     const SolverOptions& options, Result& result) {
  if (ws.factored && ws.t_factored == t && ws.q_factored == q) return true;
  return factor(sys, ws, q, t, options, result);
}

// Newton's method on Phi(q, t) = 0 from the q given.
template <class System, class WS, class VQ>
Result position(const System& sys, WS& ws, VQ& q, typename System::Scalar t,
                const SolverOptions& options) {
  using Scalar = typename System::Scalar;
  Result result;
  const Scalar inv_length = Scalar(1) / Scalar(sys.length_scale());
  for (int it = 1; it <= options.max_iterations; ++it) {
    sys.phi(q.data(), t, ws.rhs.data());
    if (!all_finite(ws.rhs) || !all_finite(q)) {
      result.status = Status::kNonFinite;
      return result;
    }
    if (!factor(sys, ws, q, t, options, result)) return result;
    ws.dq = ws.lu.solve(ws.rhs);
    q -= ws.dq;
    ws.factored = false;  // q moved
    // Scaled step: coordinates come as [x, y, phi] per body.
    double step = 0;
    for (int k = 0; k < q.size(); ++k) {
      const Scalar d = k % 3 == 2 ? ws.dq[k] : ws.dq[k] * inv_length;
      step = std::max(step, static_cast<double>(std::abs(d)));
    }
    result.iterations = it;
    result.step = step;
    if (!std::isfinite(step)) {
      result.status = Status::kNonFinite;
      return result;
    }
    if (step <= options.tolerance) return result;
  }
  result.status = Status::kMaxIterations;
  return result;
}

// Phi_q qd = nu
template <class System, class WS, class VQ>
Result velocity(const System& sys, WS& ws, const VQ& q, typename System::Scalar t, VQ& qd,
                const SolverOptions& options) {
  Result result;
  if (!ensure_factored(sys, ws, q, t, options, result)) return result;
  sys.nu(q.data(), t, ws.rhs.data());
  qd = ws.lu.solve(ws.rhs);
  if (!all_finite(qd)) result.status = Status::kNonFinite;
  return result;
}

// Phi_q qdd = gamma
template <class System, class WS, class VQ>
Result acceleration(const System& sys, WS& ws, const VQ& q, const VQ& qd,
                    typename System::Scalar t, VQ& qdd, const SolverOptions& options) {
  Result result;
  if (!ensure_factored(sys, ws, q, t, options, result)) return result;
  sys.gamma(q.data(), qd.data(), t, ws.rhs.data());
  qdd = ws.lu.solve(ws.rhs);
  if (!all_finite(qdd)) result.status = Status::kNonFinite;
  return result;
}

}  // namespace detail

// Adapts a generated model (static functions over a Params struct) to the runtime.
template <class Model, class S = double>
class GeneratedSystem {
 public:
  using Scalar = S;
  using Params = typename Model::Params;
  static constexpr int kNq = Model::nq;
  static constexpr int kNc = Model::nc;

  explicit GeneratedSystem(const Params& params = Params{}) : params_(params) {}

  const Params& params() const { return params_; }
  Params& params() { return params_; }
  int nq() const { return kNq; }
  int nc() const { return kNc; }
  double length_scale() const { return Model::length_scale; }

  void phi(const Scalar* q, Scalar t, Scalar* out) const { Model::phi(q, t, params_, out); }
  void nu(const Scalar* q, Scalar t, Scalar* out) const { Model::nu(q, t, params_, out); }
  void gamma(const Scalar* q, const Scalar* qd, Scalar t, Scalar* out) const {
    Model::gamma(q, qd, t, params_, out);
  }
  // Scatters the structural non-zeros; the other entries of `jac` stay zero.
  template <class Matrix>
  void jacobian(const Scalar* q, Scalar t, Matrix& jac) const {
    Scalar values[Model::jac_nnz > 0 ? Model::jac_nnz : 1];
    Model::phi_q(q, t, params_, values);
    for (int k = 0; k < Model::jac_nnz; ++k) jac(Model::jac_rows[k], Model::jac_cols[k]) = values[k];
  }

 private:
  Params params_;
};

// Position, velocity and acceleration analysis over any system; sizes fixed when the system
// says so at compile time.
template <class System, int NQ = System::kNq, int NC = System::kNc>
class BasicSolver {
 public:
  using Scalar = typename System::Scalar;
  using Vector = Eigen::Matrix<Scalar, NQ, 1>;
  static_assert(NQ == NC || NQ == Eigen::Dynamic || NC == Eigen::Dynamic,
                "kinegen::Solver needs a kinematically driven model: as many constraint "
                "equations as coordinates (nc == nq)");

  explicit BasicSolver(System system, SolverOptions options = {})
      : system_(std::move(system)), options_(options), ws_(system_.nq(), system_.nc()) {}

  // Newton from the q given; q is overwritten with the solution (or the last iterate).
  Result position(Vector& q, Scalar t) { return detail::position(system_, ws_, q, t, options_); }
  // Solves Phi_q qd = nu at a solved q.
  Result velocity(const Vector& q, Scalar t, Vector& qd) {
    return detail::velocity(system_, ws_, q, t, qd, options_);
  }
  // Solves Phi_q qdd = gamma at a solved q and qd; reuses the velocity's factorization.
  Result acceleration(const Vector& q, const Vector& qd, Scalar t, Vector& qdd) {
    return detail::acceleration(system_, ws_, q, qd, t, qdd, options_);
  }

  const System& system() const { return system_; }
  System& system() { return system_; }
  const SolverOptions& options() const { return options_; }
  SolverOptions& options() { return options_; }
  // Phi_q as last evaluated (valid after a velocity or acceleration call).
  const auto& jacobian() const { return ws_.jac; }

 private:
  System system_;
  SolverOptions options_;
  detail::Workspace<Scalar, NQ, NC> ws_;
};

// Dense Newton on a generated model (one LU of the whole Phi_q): the baseline, and the path
// for models without a block solver. kinegen::Solver (block_solver.hpp) is the default.
template <class Model, class Scalar = double>
class DenseSolver : public BasicSolver<GeneratedSystem<Model, Scalar>> {
  using Base = BasicSolver<GeneratedSystem<Model, Scalar>>;

 public:
  using Params = typename Model::Params;
  using typename Base::Vector;

  DenseSolver() : Base(GeneratedSystem<Model, Scalar>()) {}
  explicit DenseSolver(const Params& params, SolverOptions options = {})
      : Base(GeneratedSystem<Model, Scalar>(params), options) {}

  // The model's initial estimates as a vector of this solver's scalar.
  static Vector initial_estimate() {
    Vector q;
    for (int k = 0; k < Model::nq; ++k) q[k] = Scalar(Model::q0[k]);
    return q;
  }
};

}  // namespace kinegen

// kinegen::Solver: the generated block solver where the model has one, else DenseSolver.
#include "kinegen/block_solver.hpp"
