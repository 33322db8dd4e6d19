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
#include <type_traits>

#include "kinegen/condition_estimate.hpp"
#include "kinegen/motion.hpp"
#include "kinegen/kernels/newton.hpp"

namespace kinegen {

// Why a solve stopped.
enum class Status {
  kConverged,        // success
  kMaxIterations,    // Newton did not converge within the iteration budget
  kSingular,         // Phi_q is singular or nearly so at the current configuration
  kNonFinite,        // a residual, Jacobian or step contained NaN or infinity
  kInconsistent,     // Newton's step vanished but Phi is not zero: no solution near here
  kBudgetExhausted,  // a fixed iteration budget ran out with the residual above tolerance
  kBranchJump,       // converged, but on another assembly branch than the motion's
  kTooFar,           // a first solve's continuation would take more than kMaxContinuationSteps
};

static_assert(static_cast<int>(Status::kBranchJump) == kernels::ReportKernel::_kStatusBranchJump &&
              static_cast<int>(Status::kTooFar) == kernels::ReportKernel::_kStatusTooFar);

inline const char* to_string(Status s) {
  switch (s) {
    case Status::kConverged: return "converged";
    case Status::kMaxIterations: return "Newton iteration did not converge";
    case Status::kSingular: return "the constraint Jacobian Phi_q is singular";
    case Status::kNonFinite: return "a non-finite value (NaN or infinity) appeared";
    case Status::kInconsistent:
      return "Newton's step vanished but the constraints are not satisfied (they contradict "
             "each other, or the mechanism cannot reach this position)";
    case Status::kBudgetExhausted:
      return "the fixed iteration budget ran out with the constraints not yet satisfied";
    case Status::kBranchJump:
      return "the solution jumped to another assembly branch (a block's determinant changed "
             "sign, or the position is not the one the velocities predict)";
    case Status::kTooFar:
      return "the first solve would have to follow the drivers too far from the start pose "
             "(more than 100000 continuation steps): start from a pose near t";
  }
  return "unknown";
}

// The outcome of a solve: true on success, and why not otherwise.
struct Result {
  Status status = Status::kConverged;
  int iterations = 0;   // Newton iterations taken (position only)
  double step = 0;      // the last scaled Newton step (position only)
  double pivot_ratio = 1;  // smallest / largest |pivot| of the last (scaled) factorization
  // Estimated condition number of the scaled Phi_q of the last factorization (rows equilibrated,
  // columns multiplied by their coordinate's scale): infinity when singular; NaN when not
  // estimated (the block path on headers whose kernels estimate none).
  double condition = 1;
  // Largest scaled |Phi| after the last step, less its rounding (position only; the block path
  // measures it from Model::phi when the kernels do not report it).
  double residual = 0;
  int rank = 0;  // numerical rank of Phi_q at the last factorization (block path: nq on success)
  int block = -1;       // block solver: the block that failed (-1: none, or the dense path)

  explicit operator bool() const { return status == Status::kConverged; }
  const char* message() const { return to_string(status); }
};

struct SolverOptions {
  // Newton stops when the step, each coordinate divided by its scale (coordinate_scale: a
  // body's x and y by its joints' geometry; angles in radians), is at most this (plus the rounding
  // of the coordinate itself, 64 eps (1 + |q|), which no solver can beat: an angle of 6e6 rad is
  // only known to about 1e-9). Convergence is quadratic, so the position is then accurate to far
  // below it. Converging only linearly (each step more than a quarter of the one before) with a
  // condition estimate worse than sqrt(min_rcond) is a singular Phi_q (kernels/newton.hpp).
  double tolerance = 1e-10;
  int max_iterations = 30;
  // Phi_q counts as singular when the reciprocal of its scaled condition estimate is below this.
  // Block path: against the kernels' per-block estimate where the header reports one
  // (BlockReport::rcond); older headers check singular_pivot_ratio only.
  double min_rcond = 1e-12;
  // After the step criterion holds, every |Phi_r| must also be at most this times the row's
  // scale (|Phi_q row| with columns scaled) plus the rounding of its terms; the step alone can
  // miss a stalled least-squares iteration on contradictory constraints. Every path checks it,
  // fixed iteration counts included (kBudgetExhausted).
  double residual_tolerance = 1e-8;
  // Backtracking: a Newton step that increases the scaled residual is halved up to this many
  // times, which keeps large updates from throwing the iteration onto another branch. Block
  // path: passed to the kernels where their BlockOptions take it (older headers: no damping).
  int max_halvings = 8;
  // The LU pivot ratio below which Phi_q (or a block of it, in the block solver) counts as
  // singular; the dense path also checks min_rcond, so this is only its backstop there.
  double singular_pivot_ratio = 1e-13;
  // Block solver (block_solver.hpp) only: when positive, exactly this many Newton iterations
  // per block and no convergence test, for a fixed cost per step (real-time use).
  int fixed_iterations = 0;
  // Solver::step: a solved position that misses every velocity-based estimate of the step by
  // more than this fraction of the motion over it is a jump to another branch
  // (Status::kBranchJump; check_motion in motion.hpp, as `kinegen analyze` applies it).
  double jump_fraction = 0.25;
  // Solver::step only: when positive, a refused step (its solve failed, or it jumped) is retried
  // in halves, each halved again while refused, down to 1 / 2^substep_halvings of its length
  // (substeps in motion.hpp); only the last sub-step lands on t. `kinegen analyze` always
  // sub-steps (kAnalyzeSubstepHalvings), and a Solver with the same count takes the same
  // sub-steps bit for bit. 0, the default: a refused step fails at once, for a fixed cost per
  // step (real-time loops).
  int substep_halvings = 0;
};

// SolverOptions whose tolerances follow the precision of Scalar (its real type), as the block
// kernels' defaults do (kernels/report.hpp): for double they are the defaults above to within
// rounding, for float they are loose enough for float to meet.
template <class Scalar>
SolverOptions default_options() {
  using Real = typename Eigen::NumTraits<Scalar>::Real;
  const kernels::ReportKernel::BasicBlockOptions<Real> k;
  SolverOptions o;
  o.tolerance = static_cast<double>(k.tolerance);
  o.residual_tolerance = static_cast<double>(k.residual_tolerance);
  o.singular_pivot_ratio = static_cast<double>(k.singular_pivot_ratio);
  o.min_rcond = static_cast<double>(k.min_rcond);
  return o;
}

namespace detail {

// Storage for one analysis: Phi_q, its factorization and the vectors around it. When the sizes
// may differ (nc > nq: redundant constraints, run-time sizes only), a column-pivoted QR gives the
// least-squares Newton step, which is the exact step for a consistent redundant system.
template <class Scalar, int NQ, int NC>
struct Workspace {
  using Jacobian = Eigen::Matrix<Scalar, NC, NQ>;
  using Square = Eigen::Matrix<Scalar, NQ, NQ>;
  using VectorQ = Eigen::Matrix<Scalar, NQ, 1>;
  using VectorC = Eigen::Matrix<Scalar, NC, 1>;
  static constexpr bool kMayBeRectangular =
      NQ == Eigen::Dynamic || NC == Eigen::Dynamic || NQ != NC;
  struct NoQr {
    explicit NoQr(int, int) {}
  };
  using Qr = std::conditional_t<kMayBeRectangular, Eigen::ColPivHouseholderQR<Jacobian>, NoQr>;

  explicit Workspace(int nq = NQ, int nc = NC)
      : jac(Jacobian::Zero(nc, nq)),
        scaled(Jacobian::Zero(nc, nq)),
        rhs(nc),
        rhs_new(nc),
        row_scale(nc),
        col_scale(nq),
        dq(nq),
        q_factored(nq),
        q_trial(nq),
        est_x(nq),
        est_y(nq),
        est_z(nq),
        lu(nq),
        qr(nc, nq) {}

  bool rectangular() const { return jac.rows() != jac.cols(); }

  Jacobian jac;     // Phi_q
  Jacobian scaled;  // R Phi_q D: rows equilibrated, columns times their coordinate's scale
  VectorC rhs, rhs_new;
  VectorC row_scale;  // R (1 / row norm of Phi_q D)
  VectorQ col_scale;  // D (each coordinate's scale: coordinate_scale)
  VectorQ dq;
  VectorQ q_factored;  // where the factorization was computed
  VectorQ q_trial;
  VectorQ est_x, est_y, est_z;  // condition estimate
  Scalar t_factored = Scalar(0);
  bool factored = false;
  int det_sign = 0;  // sign of det(Phi_q) at the last square factorization (0 if unknown)
  Eigen::PartialPivLU<Square> lu;
  Qr qr;
};

template <class Derived>
bool all_finite(const Eigen::MatrixBase<Derived>& v) {
  return v.allFinite();
}

// hager_reciprocal_condition for the factored dense scaled Phi_q.
template <class WS>
double reciprocal_condition(WS& ws) {
  const double norm_a = static_cast<double>(ws.scaled.cwiseAbs().colwise().sum().maxCoeff());
  return hager_reciprocal_condition(ws, norm_a, static_cast<int>(ws.scaled.cols()));
}

// Evaluates Phi_q at (q, t), scales it and factors it. Fills `result` (condition, rank; status
// on failure).
template <class System, class WS, class VQ>
bool factor(const System& sys, WS& ws, const VQ& q, typename System::Scalar t,
            const SolverOptions& options, Result& result) {
  using Scalar = typename System::Scalar;
  sys.jacobian(q.data(), t, ws.jac);
  ws.factored = false;
  ws.det_sign = 0;
  if (!all_finite(ws.jac)) {
    result.status = Status::kNonFinite;
    return false;
  }
  for (int k = 0; k < ws.col_scale.size(); ++k) ws.col_scale[k] = Scalar(coordinate_scale(sys, k));
  ws.scaled = ws.jac * ws.col_scale.asDiagonal();
  for (int r = 0; r < ws.scaled.rows(); ++r) {
    const Scalar n = ws.scaled.row(r).cwiseAbs().maxCoeff();
    ws.row_scale[r] = n > Scalar(0) ? Scalar(1) / n : Scalar(1);
  }
  ws.scaled = ws.row_scale.asDiagonal() * ws.scaled;
  const int nq = static_cast<int>(ws.jac.cols());
  double rcond = 0;
  if constexpr (WS::kMayBeRectangular) {
    if (ws.rectangular()) {
      ws.qr.setThreshold(options.min_rcond);
      ws.qr.compute(ws.scaled);
      const auto diag = ws.qr.matrixR().diagonal().cwiseAbs();
      const double largest = static_cast<double>(diag.maxCoeff());
      const double smallest = static_cast<double>(diag.minCoeff());
      rcond = largest > 0 ? smallest / largest : 0.0;
      result.pivot_ratio = rcond;
      result.rank = static_cast<int>(ws.qr.rank());
      result.condition = rcond > 0 ? 1 / rcond : std::numeric_limits<double>::infinity();
      if (ws.jac.rows() < nq || !(rcond > options.min_rcond)) {
        result.status = Status::kSingular;
        return false;
      }
      ws.q_factored = q;
      ws.t_factored = t;
      ws.factored = true;
      return true;
    }
  }
  ws.lu.compute(ws.scaled);
  const auto diag = ws.lu.matrixLU().diagonal().cwiseAbs();
  const double largest = static_cast<double>(diag.maxCoeff());
  const double smallest = static_cast<double>(diag.minCoeff());
  result.pivot_ratio = largest > 0 ? smallest / largest : 0.0;
  rcond = result.pivot_ratio > 0 ? reciprocal_condition(ws) : 0.0;
  result.condition = rcond > 0 ? 1 / rcond : std::numeric_limits<double>::infinity();
  result.rank = nq;
  if (!(rcond > options.min_rcond) || !(result.pivot_ratio > options.singular_pivot_ratio)) {
    result.rank = nq - 1;  // at least
    result.status = Status::kSingular;
    return false;
  }
  const double det = static_cast<double>(std::real(ws.lu.determinant()));
  ws.det_sign = det > 0 ? 1 : (det < 0 ? -1 : 0);
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

// Solves Phi_q x = ws.rhs (least squares when redundant) with the scaled factorization.
template <class WS, class VQ>
void solve_factored(WS& ws, VQ& x) {
  ws.rhs = ws.row_scale.asDiagonal() * ws.rhs;
  if constexpr (WS::kMayBeRectangular) {
    if (ws.rectangular()) {
      x = ws.qr.solve(ws.rhs);
      x = ws.col_scale.asDiagonal() * x;
      return;
    }
  }
  x = ws.lu.solve(ws.rhs);
  x = ws.col_scale.asDiagonal() * x;
}

// Largest |Phi_r| measured against the row's scale, less the rounding allowance of the row's
// terms (the Newton policy's, kernels/newton.hpp, on the scaled sum of |Phi_q entry| |q|), so
// that huge angles are judged fairly: the residual recheck holds when it is at most
// residual_tolerance. `rounding` receives the largest allowance.
template <class WS, class V, class VQ>
double scaled_residual(const WS& ws, const V& phi, const VQ& q, double& rounding) {
  using Real = typename Eigen::NumTraits<typename V::Scalar>::Real;
  const double eps = static_cast<double>(std::numeric_limits<Real>::epsilon());
  double worst = 0;
  rounding = 0;
  for (int r = 0; r < phi.size(); ++r) {
    const double scale = static_cast<double>(std::abs(ws.row_scale[r]));
    double terms = 0;
    for (int k = 0; k < q.size(); ++k)
      terms += static_cast<double>(std::abs(ws.jac(r, k)) * std::abs(q[k]));
    const double round = kernels::NewtonKernel::_rounding(terms * scale, eps);
    const double excess = static_cast<double>(std::abs(phi[r])) * scale - round;
    worst = std::max(worst, excess);
    rounding = std::max(rounding, round);
  }
  return worst;
}

template <class WS, class V>
double residual_norm(const WS& ws, const V& phi) {
  double n = 0;
  for (int r = 0; r < phi.size(); ++r)
    n = std::max(n, static_cast<double>(std::abs(phi[r] * ws.row_scale[r])));
  return n;
}

// Damped Newton's method on Phi(q, t) = 0 from the q given (Gauss-Newton when redundant), with
// the Newton policy of kernels/newton.hpp: the step criterion, the residual recheck, the
// linear-convergence rule and the verdict are the block path's; the damping is this path's
// own (SolverOptions::max_halvings; the blocks do not damp).
template <class System, class WS, class VQ>
Result position(const System& sys, WS& ws, VQ& q, typename System::Scalar t,
                const SolverOptions& options) {
  using Scalar = typename System::Scalar;
  using Newton = kernels::NewtonKernel;
  using std::abs;
  Result result;
  const double eps =
      static_cast<double>(std::numeric_limits<typename Eigen::NumTraits<Scalar>::Real>::epsilon());
  sys.phi(q.data(), t, ws.rhs.data());
  bool converged = false;
  double step = 0;       // the last scaled step
  int linear_steps = 0;  // steps that shrank by less than the policy's kLinearRatio
  for (int it = 1; it <= options.max_iterations && !converged; ++it) {
    if (!all_finite(ws.rhs) || !all_finite(q)) {
      result.status = Status::kNonFinite;
      return result;
    }
    if (!factor(sys, ws, q, t, options, result)) return result;
    const double old_norm = residual_norm(ws, ws.rhs);
    solve_factored(ws, ws.dq);  // scales ws.rhs in place
    // Backtracking: halve a step that makes the residual grow (never below 1/2^max_halvings).
    Scalar alpha = Scalar(1);
    for (int h = 0;; ++h) {
      ws.q_trial = q - alpha * ws.dq;
      sys.phi(ws.q_trial.data(), t, ws.rhs_new.data());
      if (Newton::_accept_step(residual_norm(ws, ws.rhs_new), old_norm, h, options.max_halvings,
                               eps))
        break;
      alpha /= Scalar(2);
    }
    q = ws.q_trial;
    ws.rhs = ws.rhs_new;
    ws.factored = false;  // q moved
    const double previous = step;
    step = 0;
    bool small = true;
    for (int k = 0; k < q.size(); ++k) {
      const double scale_k = static_cast<double>(abs(ws.col_scale[k]));
      const double d = static_cast<double>(abs(alpha * ws.dq[k])) / scale_k;
      const double qk = static_cast<double>(abs(q[k])) / scale_k;
      step = std::max(step, d);
      small = small && Newton::_step_converged(d, qk, options.tolerance, eps);
    }
    result.iterations = it;
    result.step = step;
    if (!std::isfinite(step)) {
      result.status = Status::kNonFinite;
      return result;
    }
    linear_steps += Newton::_linear_step(step, previous);
    // A damped step is no evidence of convergence: only a full one ends the iteration.
    converged = small && alpha == Scalar(1);
  }
  double rounding = 0;
  result.residual = scaled_residual(ws, ws.rhs, q, rounding);
  const double rcond = result.condition > 0 ? 1 / result.condition : 0.0;
  const bool linear = linear_steps >= Newton::kLinearSteps;
  result.status = static_cast<Status>(
      Newton::_newton_status(false, converged, result.residual <= options.residual_tolerance,
                             linear, result.residual, rcond, options.min_rcond));
  return result;
}

// First solves (docs/embedding.md, "First solves and branches"). A Newton solve straight
// from the start pose (normally the file's q0) at a time where it does not fit can land on
// another assembly. Instead the first solve follows the drivers there: with offset = Phi(q_start,
// t), it solves Phi(q, t) = (1 - s) offset for s = 1/n, 2/n, ..., 1, each from the last, so
// that each driven quantity moves from its value at the start pose to its value at t in steps
// of at most kContinuationAngle rad or kContinuationLength length scales. Rows the start pose
// satisfies (joints) keep offset 0, so only the drivers move.
inline constexpr double kContinuationAngle = 0.25;
inline constexpr double kContinuationLength = 0.1;
inline constexpr int kMaxContinuationSteps = kernels::ReportKernel::_kMaxContinuationSteps;
inline constexpr double kHalfTurn = 3.14159265358979323846;

template <class System, class = void>
struct HasCoordinateKind : std::false_type {};
template <class System>
struct HasCoordinateKind<System,
                         std::void_t<decltype(std::declval<const System&>().coordinate_kind(0))>>
    : std::true_type {};
template <class System>
CoordinateKind coordinate_kind(const System& sys, int k) {
  if constexpr (HasCoordinateKind<System>::value) {
    return sys.coordinate_kind(k);
  } else {
    return body_coordinate_kind(k);
  }
}

// Accumulates, row by row, how many continuation steps the offset needs: a row's driven
// quantity changes by |offset_r| / |dPhi_r/dq_k|, k its largest scaled entry, whose kind
// sets the step (an angle: kContinuationAngle; else kContinuationLength length scales).
class ContinuationSteps {
 public:
  explicit ContinuationSteps(double length_scale) : length_(length_scale) {}
  // One row: |offset|, and |dPhi_r/dq_k| and the kind of its largest scaled entry.
  void add_row(double offset, double entry, CoordinateKind kind) {
    const double limit =
        kind == CoordinateKind::kAngle ? kContinuationAngle : kContinuationLength * length_;
    const double need = offset == 0 ? 0.0 : offset / (entry * limit);
    if (!(need <= worst_)) worst_ = need;  // NaN sticks
  }
  bool finite() const { return worst_ == worst_ && worst_ < 1e300; }
  // Steps to take: 1 when the start pose fits (an ordinary solve).
  double count() const { return std::max(1.0, std::ceil(worst_)); }

 private:
  double length_;
  double worst_ = 0;
};

// The continuation's system: Phi(q, t) - w offset; Phi_q is the system's.
template <class System>
class OffsetSystem {
 public:
  using Scalar = typename System::Scalar;
  static constexpr int kNq = System::kNq;
  static constexpr int kNc = System::kNc;
  OffsetSystem(const System& sys, const Scalar* offset, Scalar weight)
      : sys_(sys), offset_(offset), weight_(weight) {}
  int nq() const { return sys_.nq(); }
  int nc() const { return sys_.nc(); }
  double length_scale() const { return sys_.length_scale(); }
  double coordinate_scale(int k) const { return detail::coordinate_scale(sys_, k); }
  void phi(const Scalar* q, Scalar t, Scalar* out) const {
    sys_.phi(q, t, out);
    for (int r = 0; r < sys_.nc(); ++r) out[r] -= weight_ * offset_[r];
  }
  template <class Matrix>
  void jacobian(const Scalar* q, Scalar t, Matrix& jac) const {
    sys_.jacobian(q, t, jac);
  }

 private:
  const System& sys_;
  const Scalar* offset_;
  Scalar weight_;
};

// The continuation's plan at the start pose q (first_position): Phi(q, t) into offset and
// Phi_q into ws.jac, and the steps it needs (count() 1: q fits; not finite() when Phi or Phi_q
// is not finite there).
template <class System, class WS, class VQ, class VC>
ContinuationSteps continuation_plan(const System& sys, WS& ws, const VQ& q,
                                    typename System::Scalar t, VC& offset) {
  using std::abs;
  ContinuationSteps steps(sys.length_scale());
  sys.phi(q.data(), t, offset.data());
  sys.jacobian(q.data(), t, ws.jac);
  ws.factored = false;
  if (!all_finite(offset) || !all_finite(ws.jac) || !all_finite(q)) {
    steps.add_row(std::numeric_limits<double>::quiet_NaN(), 1, CoordinateKind::kLength);
    return steps;
  }
  for (int r = 0; r < offset.size(); ++r) {
    int best = -1;
    double size = 0;
    for (int k = 0; k < ws.jac.cols(); ++k) {
      const double v = static_cast<double>(abs(ws.jac(r, k))) * coordinate_scale(sys, k);
      if (v > size) size = v, best = k;
    }
    if (best >= 0)
      steps.add_row(static_cast<double>(abs(offset[r])), static_cast<double>(abs(ws.jac(r, best))),
                    coordinate_kind(sys, best));
  }
  return steps;
}

// The dense path's first solve: the continuation above, each step by position(), its
// determinant sign checked against the first step's (a rough q0 is no assembly: the first
// step's solution is) and its angles against the step before (a sign change, or an angle that
// moved by half a turn or more in one step, is a jump: kBranchJump). On success q
// is the solution at t. steps, when given, receives the number of continuation steps (1: the
// start pose fitted, an ordinary solve).
template <class System, class WS, class VQ>
Result first_position(const System& sys, WS& ws, VQ& q, typename System::Scalar t,
                      const SolverOptions& options, int* steps_taken = nullptr) {
  using Scalar = typename System::Scalar;
  using std::abs;
  Result result;
  typename WS::VectorC offset(ws.rhs.size());
  const ContinuationSteps steps = continuation_plan(sys, ws, q, t, offset);
  if (!steps.finite()) {
    result.status = Status::kNonFinite;
    return result;
  }
  if (steps_taken)
    *steps_taken = static_cast<int>(std::min(steps.count(), 2.0 * kMaxContinuationSteps));
  if (steps.count() <= 1) return position(sys, ws, q, t, options);
  if (steps.count() > kMaxContinuationSteps) {
    // A row whose entries vanish needs endless steps: that is a singular Phi_q, so named.
    if (!factor(sys, ws, q, t, options, result)) return result;
    ws.factored = false;
    result.status = Status::kTooFar;
    return result;
  }
  const int n = static_cast<int>(steps.count());
  int sign = 0;  // det(Phi_q)'s at the first step's solution, the assembly the steps continue
  VQ before = q;
  for (int i = 1; i <= n; ++i) {
    const OffsetSystem<System> path(sys, offset.data(), Scalar(n - i) / Scalar(n));
    before = q;
    result = position(path, ws, q, t, options);
    if (!result) return result;
    if (i == 1) sign = ws.det_sign;
    bool jumped = ws.det_sign != sign;
    for (int k = 0; k < q.size(); ++k)
      if (coordinate_kind(sys, k) == CoordinateKind::kAngle &&
          !(static_cast<double>(abs(q[k] - before[k])) < kHalfTurn))
        jumped = true;
    if (jumped) {
      result.status = Status::kBranchJump;
      return result;
    }
  }
  ws.factored = false;
  return result;
}

// Phi_q qd = nu
template <class System, class WS, class VQ>
Result velocity(const System& sys, WS& ws, const VQ& q, typename System::Scalar t, VQ& qd,
                const SolverOptions& options) {
  Result result;
  if (!ensure_factored(sys, ws, q, t, options, result)) return result;
  sys.nu(q.data(), t, ws.rhs.data());
  solve_factored(ws, qd);
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
  solve_factored(ws, qdd);
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
  double coordinate_scale(int k) const { return detail::model_coordinate_scale<Model>(k); }
  CoordinateKind coordinate_kind(int k) const { return detail::model_coordinate_kind<Model>(k); }

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
  // A first solve: from the q given (the start pose, normally the model's q0) to t by
  // continuation of the drivers (detail::first_position), so that it lands on the assembly
  // the motion from the start pose reaches, or fails.
  // steps, when given, receives the number of continuation steps (1: an ordinary solve).
  Result first_position(Vector& q, Scalar t, int* steps = nullptr) {
    return detail::first_position(system_, ws_, q, t, options_, steps);
  }
  // The continuation steps first_position would take from q at t (1: q fits, an ordinary
  // solve; NaN: Phi or Phi_q is not finite there).
  double first_steps(const Vector& q, Scalar t) {
    typename detail::Workspace<Scalar, NQ, NC>::VectorC offset(ws_.rhs.size());
    const detail::ContinuationSteps steps = detail::continuation_plan(system_, ws_, q, t, offset);
    return steps.finite() ? steps.count() : std::numeric_limits<double>::quiet_NaN();
  }
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
  // Sign of det(Phi_q) at the last square factorization (0 when unknown or not square): it
  // changes only through a singular configuration, so a change between two solved steps
  // means the solution crossed one or jumped to another assembly branch.
  int jacobian_sign() const { return ws_.det_sign; }

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
