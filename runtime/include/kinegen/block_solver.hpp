// kinegen::Solver: drives a generated model's block solver (position, velocity and
// acceleration block by block in block-lower-triangular order, see docs/performance.md) when
// the header has one, and falls back to DenseSolver otherwise. Adds a full step with a Taylor
// predictor. Header-only, Eigen and std only, allocation-free.
#pragma once

#include <array>
#include <cstring>
#include <limits>
#include <type_traits>

#include "kinegen/block_options.hpp"
#include "kinegen/driver_continuation.hpp"
#include "kinegen/motion.hpp"
#include "kinegen/solver.hpp"

namespace kinegen {

namespace detail {

// Whether a generated header carries block functions (older headers do not).
template <class Model, class = void>
struct HasBlockSolver : std::false_type {};
template <class Model>
struct HasBlockSolver<Model, std::void_t<decltype(Model::has_block_solver)>>
    : std::bool_constant<Model::has_block_solver> {};

template <class Model, class = void>
struct HasAcceleration : std::true_type {};  // headers before --outputs had everything
template <class Model>
struct HasAcceleration<Model, std::void_t<decltype(Model::has_acceleration)>>
    : std::bool_constant<Model::has_acceleration> {};

// Size of the generated sin/cos cache (0: none, or a header from before it existed).
template <class Model, class = void>
struct TrigCacheSize : std::integral_constant<int, 0> {};
template <class Model>
struct TrigCacheSize<Model, std::void_t<decltype(Model::trig_cache_size)>>
    : std::integral_constant<int, Model::trig_cache_size> {};

// Whether the header lists the coordinates Newton iterates (newton_coordinates).
template <class Model, class = void>
struct HasNewtonCoordinates : std::false_type {};
template <class Model>
struct HasNewtonCoordinates<Model, std::void_t<decltype(Model::newton_coordinates)>>
    : std::true_type {};

// Fields that newer headers' BlockReport and BlockOptions carry (detection, so that older
// headers keep working): the residual and condition the kernels measured, the option fields
// they honour, and solve functions that report each block's determinant sign.
template <class R, class = void>
struct ReportHasResidual : std::false_type {};
template <class R>
struct ReportHasResidual<R, std::void_t<decltype(std::declval<const R&>().residual)>>
    : std::true_type {};
template <class R, class = void>
struct ReportHasRcond : std::false_type {};
template <class R>
struct ReportHasRcond<R, std::void_t<decltype(std::declval<const R&>().rcond)>> : std::true_type {};
// Whether the header has parameter sensitivities (phi_p, solve_sensitivity), and how many
// parameters its Params has (0 when it does not say).
template <class Model, class = void>
struct HasSensitivity : std::false_type {};
template <class Model>
struct HasSensitivity<Model, std::void_t<decltype(Model::has_sensitivity)>>
    : std::bool_constant<Model::has_sensitivity> {};
template <class Model, class = void>
struct NumParams : std::integral_constant<int, 0> {};
template <class Model>
struct NumParams<Model, std::void_t<decltype(Model::num_params)>>
    : std::integral_constant<int, Model::num_params> {};
template <class Model, class = void>
struct NumBlocks : std::integral_constant<int, 0> {};
template <class Model>
struct NumBlocks<Model, std::void_t<decltype(Model::num_blocks)>>
    : std::integral_constant<int, Model::num_blocks> {};

// Whether the header has the kinetostatics (solve_forces, force_columns), and whether its
// solve_step keeps its factors for them (StepFactors).
template <class Model, class = void>
struct HasForces : std::false_type {};
template <class Model>
struct HasForces<Model, std::void_t<decltype(Model::has_forces)>>
    : std::bool_constant<Model::has_forces> {};
template <class Model, class = void>
struct HasStepFactors : std::false_type {};
template <class Model>
struct HasStepFactors<Model, std::void_t<typename Model::template StepFactors<double>>>
    : std::true_type {};
// The header's StepFactors<Scalar>, or an empty struct for headers without it.
struct NoStepFactors {};
template <class Model, class Scalar, bool = HasStepFactors<Model>::value>
struct StepFactorsOf {
  using type = NoStepFactors;
};
template <class Model, class Scalar>
struct StepFactorsOf<Model, Scalar, true> {
  using type = typename Model::template StepFactors<Scalar>;
};
template <class Model, class = void>
struct NumForceColumns : std::integral_constant<int, 1> {};
template <class Model>
struct NumForceColumns<Model, std::void_t<decltype(Model::num_force_columns)>>
    : std::integral_constant<int, Model::num_force_columns> {};

// The block solver's report as a Result. What the report does not carry is left for Solver
// to fill in (the residual) or marked unknown (condition NaN: older kernels estimate none).
template <class Model, class Report>
Result to_result(const Report& report) {
  Result r;
  r.status = static_cast<Status>(report.status);
  r.iterations = report.iterations;
  r.step = report.step;
  r.block = report.block;
  r.rank = Model::nq;  // every block's LU passed its pivot test
  r.condition = std::numeric_limits<double>::quiet_NaN();
  r.pivot_ratio = std::numeric_limits<double>::quiet_NaN();
  if constexpr (ReportHasResidual<Report>::value) r.residual = static_cast<double>(report.residual);
  if constexpr (ReportHasRcond<Report>::value) {
    const double rcond = static_cast<double>(report.rcond);
    r.condition = rcond > 0 ? 1 / rcond : std::numeric_limits<double>::infinity();
  }
  if (r.status == Status::kSingular) {
    r.pivot_ratio = 0;
    r.rank = Model::nq - 1;  // at most
    r.condition = std::numeric_limits<double>::infinity();
  }
  return r;
}

// Largest |Phi_r| of a generated model at q, against the row's scale (the largest
// |dPhi_r/dq_k| times coordinate k's scale) less the rounding of the row's terms: the measure
// of detail::scaled_residual, on the structural non-zeros only (nothing of nq x nc).
template <class Model, class Scalar>
double model_residual(const Scalar* q, Scalar t, const typename Model::Params& params) {
  using std::abs;
  Scalar phi[Model::nc];
  Scalar values[Model::jac_nnz > 0 ? Model::jac_nnz : 1];
  double row_size[Model::nc] = {}, terms[Model::nc] = {};
  Model::phi(q, t, params, phi);
  Model::phi_q(q, t, params, values);
  for (int e = 0; e < Model::jac_nnz; ++e) {
    const int r = Model::jac_rows[e], c = Model::jac_cols[e];
    const double v = static_cast<double>(abs(values[e]));
    row_size[r] = std::max(row_size[r], v * model_coordinate_scale<Model>(c));
    terms[r] += v * static_cast<double>(abs(q[c]));
  }
  const double eps = static_cast<double>(std::numeric_limits<Scalar>::epsilon());
  double worst = 0;
  for (int r = 0; r < Model::nc; ++r) {
    const double size = row_size[r] > 0 ? row_size[r] : 1.0;
    const double excess = static_cast<double>(abs(phi[r])) / size -
                          kernels::NewtonKernel::_rounding(terms[r] / size, eps);
    if (!(excess == excess)) return excess;  // NaN: not a solution
    worst = std::max(worst, excess);
  }
  return worst;
}

}  // namespace detail

// The solver for a generated model: `kinegen::Solver<kinegen::models::four_bar> solver;`.
// position / velocity / acceleration as in BasicSolver; step() adds a predictor.
template <class Model, class Scalar = double>
class Solver {
 public:
  using Params = typename Model::Params;
  using Vector = Eigen::Matrix<Scalar, Model::nq, 1>;
  // True when the generated block functions are used; false: dense Newton on Phi_q.
  static constexpr bool kBlockSolver = detail::HasBlockSolver<Model>::value;

  // Options default to the scalar's precision (default_options<Scalar>()).
  Solver() : Solver(Params{}) {}
  explicit Solver(const Params& params, SolverOptions options = default_options<Scalar>())
      : dense_(params, options) {}

  // The model's initial estimates as a vector of this solver's scalar.
  static Vector initial_estimate() {
    Vector q;
    for (int k = 0; k < Model::nq; ++k) q[k] = Scalar(Model::q0[k]);
    return q;
  }
  const GeneratedSystem<Model, Scalar>& system() const { return dense_.system(); }
  GeneratedSystem<Model, Scalar>& system() { return dense_.system(); }
  const SolverOptions& options() const { return dense_.options(); }
  SolverOptions& options() { return dense_.options(); }

  // Newton from the q given; q is overwritten with the solution (or the last iterate).
  // Result::iterations is the largest count of any block; Result::block names the block that
  // failed. Success means the residual was checked (SolverOptions::residual_tolerance), and the
  // branch: each block's determinant sign against the first solve's, and each angle Newton
  // iterates within a turn of the q given (else Status::kBranchJump).
  // The first solve (of a new Solver, or after reset()) starts from the q given as the start
  // pose (normally initial_estimate()) and follows the drivers from their values there to t
  // by continuation (docs/embedding.md, "First solves and branches"), so that it lands on the
  // assembly the motion from that pose reaches, or fails with a status.
  Result position(Vector& q, Scalar t) {
    if constexpr (kBlockSolver) {
      if (!assembled_) {
        forget_branch();
        if (const Result c = continue_first(q, t); !c) return c;
      }
      Vector given = q;
      Result r = checked(q, t, solve_block_position(q, t, block_options()));
      if (r && assembled_ && left_turn(given, q)) r.status = Status::kBranchJump;
      if (r) assembled_ = true;
      return r;
    } else {
      Result r = assembled_ ? dense_.position(q, t) : dense_.first_position(q, t);
      if (r && !detail::branches_hold<Model>(q.data(), t, dense_.system().params()))
        r.status = Status::kBranchJump;  // a spatial header's branch conditions
      if (r) assembled_ = true;
      return r;
    }
  }
  // Solves Phi_q qd = nu at a solved q.
  Result velocity(const Vector& q, Scalar t, Vector& qd) {
    if constexpr (kBlockSolver) {
      const Result r = detail::to_result<Model>(
          Model::solve_velocity(q.data(), t, dense_.system().params(), qd.data(), block_options()));
      if (!r) qd.setConstant(kNaN);  // no stale or partial values after a failure
      return r;
    } else {
      return dense_.velocity(q, t, qd);
    }
  }
  // Solves Phi_q qdd = gamma at a solved q and qd.
  Result acceleration(const Vector& q, const Vector& qd, Scalar t, Vector& qdd) {
    if constexpr (kBlockSolver) {
      const Result r = detail::to_result<Model>(Model::solve_acceleration(
          q.data(), qd.data(), t, dense_.system().params(), qdd.data(), block_options()));
      if (!r) qdd.setConstant(kNaN);
      return r;
    } else {
      return dense_.acceleration(q, qd, t, qdd);
    }
  }

  // dq/dp, column k the sensitivity of q to parameter k (Params order).
  using SensitivityMatrix = Eigen::Matrix<Scalar, Model::nq, detail::NumParams<Model>::value>;
  static constexpr bool kSensitivity = detail::HasSensitivity<Model>::value;

  // Parameter sensitivities at a solved q (headers with has_sensitivity): the generated
  // solve_sensitivity, one factorization per block for all parameters, with this solver's
  // params and min_rcond. A singular block fails with Status::kSingular and dq_dp is NaN.
  template <bool S = kSensitivity, std::enable_if_t<S, int> = 0>
  Result sensitivity(const Vector& q, Scalar t, SensitivityMatrix& dq_dp) {
    const Result r = detail::to_result<Model>(Model::solve_sensitivity(
        q.data(), t, dense_.system().params(), dq_dp.data(), block_options()));
    if (!r) dq_dp.setConstant(kNaN);
    return r;
  }

  // Kinetostatics (headers with has_forces, docs/forces.md): lambda of Phi_q^T lambda = Q at a
  // solved q, qd, qdd, and the force_column_names columns (driver efforts, joint reactions).
  // Straight after a successful step() at the same t and q, nothing is factored again: the
  // step's factors are reused (a feedforward torque in a control loop); otherwise each block
  // is factored. A toggle position fails with Status::kSingular, and the outputs are NaN.
  static constexpr bool kForces = kBlockSolver && detail::HasForces<Model>::value;
  using LambdaVector = Eigen::Matrix<Scalar, Model::nc, 1>;
  using ForceColumns = Eigen::Matrix<Scalar, detail::NumForceColumns<Model>::value, 1>;
  template <bool F = kForces, std::enable_if_t<F, int> = 0>
  Result forces(const Vector& q, const Vector& qd, const Vector& qdd, Scalar t,
                LambdaVector& lambda) const {
    const auto& p = dense_.system().params();
    Result r;
    if constexpr (kStepFactors) {
      // The step's factors hold for its t, q, parameters and options only.
      const bool reuse =
          factors_valid_ && same_bits(t, t_factored_) &&
          std::memcmp(q.data(), q_factored_.data(), sizeof(Scalar) * Model::nq) == 0 &&
          same_bits(p, params_factored_) && same_options(dense_.options(), options_factored_);
      r = detail::to_result<Model>(Model::solve_forces(q.data(), qd.data(), qdd.data(), t, p,
                                                       lambda.data(), block_options(),
                                                       reuse ? &factors_ : nullptr));
    } else {
      r = detail::to_result<Model>(Model::solve_forces(q.data(), qd.data(), qdd.data(), t, p,
                                                       lambda.data(), block_options()));
    }
    if (!r) lambda.setConstant(kNaN);
    return r;
  }
  template <bool F = kForces, std::enable_if_t<F, int> = 0>
  Result force_columns(const Vector& q, const Vector& qd, const Vector& qdd, Scalar t,
                       ForceColumns& columns) const {
    LambdaVector lambda;
    const Result r = forces(q, qd, qdd, t, lambda);
    if (r)
      Model::force_columns(q.data(), t, dense_.system().params(), lambda.data(), columns.data());
    else
      columns.setConstant(kNaN);
    return r;
  }

  // One full step at time t: q is predicted from the last step (TaylorPredictor, none on the
  // first call or after reset()), then solved, then qd and qdd. q, qd and qdd are the caller's
  // state, passed back unchanged between steps (call reset() after changing them). A step
  // whose solution is not the one the velocities predict (check_motion: another assembly
  // branch, or a step too coarse to tell) fails with Status::kBranchJump, as does a change of
  // a block's determinant sign where the header reports them. With
  // SolverOptions::substep_halvings, a refused step is taken in sub-steps instead (as `kinegen
  // analyze` takes it), and fails only when one of 1 / 2^substep_halvings of it is refused;
  // failed_time() then says where. A failed step leaves the history as it found it.
  Result step(Scalar t, Vector& q, Vector& qd, Vector& qdd) {
    failed_at_ = t;
    const int halvings = dense_.options().substep_halvings;
    if (halvings <= 0 || !has_previous_) return single_step(t, q, qd, qdd);
    return substepped(t, halvings, q, qd, qdd);
  }
  // Where the last step() failed: its t, or the end of its refused sub-step.
  Scalar failed_time() const { return failed_at_; }
  // Forgets everything the steps kept: the predictor's history, the sin/cos cache and the
  // blocks' determinant signs. The next step() starts Newton from the q given.
  void reset() {
    has_previous_ = has_two_ = false;
    h_previous_ = t_previous_ = Scalar(0);
    qdd_before_.setZero();
    trig_ = empty_trig_cache();
    signs_.fill(0);
    signs_new_.fill(0);
    factors_valid_ = false;
    assembled_ = false;
  }

 private:
  // step() in sub-steps (motion.hpp's substeps, as analyze takes them): each starts from the
  // last accepted state, and a failure restores the history of the step's start.
  Result substepped(Scalar t, int halvings, Vector& q, Vector& qd, Vector& qdd) {
    Vector q_ok = q, qd_ok = qd, qdd_ok = qdd;
    const History entry{t_previous_,  h_previous_,    has_two_,       q_previous_,
                        qd_previous_, qdd_previous_, qdd_before_, signs_, signs_new_};
    Result r;
    const auto attempt = [&](Scalar to) {
      r = single_step(to, q, qd, qdd);
      if (!r) return false;
      q_ok = q, qd_ok = qd, qdd_ok = qdd;
      return true;
    };
    const auto restore = [&] { q = q_ok, qd = qd_ok, qdd = qdd_ok; };
    if (substeps(t_previous_, t, halvings, attempt, restore, failed_at_)) return r;
    t_previous_ = entry.t, h_previous_ = entry.h, has_two_ = entry.has_two;
    q_previous_ = entry.q, qd_previous_ = entry.qd, qdd_previous_ = entry.qdd;
    qdd_before_ = entry.qdd_before, signs_ = entry.signs, signs_new_ = entry.signs_new;
    qd.setConstant(kNaN);
    qdd.setConstant(kNaN);
    return r;
  }
  // One step from the last one, without sub-steps.
  Result single_step(Scalar t, Vector& q, Vector& qd, Vector& qdd) {
    factors_valid_ = false;
    const Scalar h = has_previous_ ? t - t_previous_ : Scalar(0);
    if (has_previous_) {
      const TaylorPredictor<Scalar> predict(h, h_previous_, has_two_);
      for_predicted([&](int k) { q[k] = predict(q[k], qd[k], qdd[k], qdd_before_[k]); });
    }
    Result r;
    if constexpr (kBlockSolver && detail::HasAcceleration<Model>::value) {
      // Without a prediction the first solve iterates to convergence even when the options
      // fix the iteration count; the very first starts by the drivers' continuation.
      auto o = block_options();
      if (!has_previous_) o.fixed_iterations = 0;
      if (!assembled_) {
        forget_branch();
        r = continue_first(q, t);
      }
      if (r) r = checked(q, t, solve_block_step(q, t, qd, qdd, o));
    } else {
      r = position(q, t);
      if (r) {
        if (const Result rv = velocity(q, t, qd); !rv) r = rv;
      }
      if (r) {
        if (const Result ra = acceleration(q, qd, t, qdd); !ra) r = ra;
      }
    }
    if (r && has_previous_ && signs_changed()) r.status = Status::kBranchJump;
    if (r && has_previous_) {
      const MotionCheck motion = check_motion(
          predicted_coordinates(), static_cast<double>(h), q_previous_, qd_previous_, qdd_previous_,
          q, qd, qdd, [](int k) { return detail::InverseCoordinateScales<Model>::kValues[k]; },
          dense_.options().jump_fraction,
          static_cast<double>(std::numeric_limits<Scalar>::epsilon()));
      if (motion.jumped()) r.status = Status::kBranchJump;
    }
    if (!r) {
      qd.setConstant(kNaN);  // no stale or partial values after a failure
      qdd.setConstant(kNaN);
      return r;
    }
    // Only solved values enter the history, so a failed step leaves nothing behind.
    has_two_ = has_previous_;
    h_previous_ = h;
    for_predicted([&](int k) {
      qdd_before_[k] = qdd_previous_[k];
      q_previous_[k] = q[k];
      qd_previous_[k] = qd[k];
      qdd_previous_[k] = qdd[k];
    });
    signs_ = signs_new_;
    t_previous_ = t;
    has_previous_ = true;
    assembled_ = true;
    if constexpr (kStepFactors) {  // forces() at this t and q reuses the step's factors
      factors_valid_ = true;
      t_factored_ = t;
      q_factored_ = q;
      params_factored_ = dense_.system().params();
      options_factored_ = dense_.options();
    }
    return r;
  }

  // Whether two values are the same bits (a NaN matches only itself, -0 is not 0), as the
  // generated _same_bits compares: a value of another source is never taken for this one.
  template <class X>
  static bool same_bits(const X& a, const X& b) {
    static_assert(std::is_trivially_copyable_v<X>);
    return std::memcmp(&a, &b, sizeof(X)) == 0;
  }
  static bool same_options(const SolverOptions& a, const SolverOptions& b) {
    return same_bits(a.tolerance, b.tolerance) && a.max_iterations == b.max_iterations &&
           same_bits(a.min_rcond, b.min_rcond) &&
           same_bits(a.residual_tolerance, b.residual_tolerance) &&
           a.max_halvings == b.max_halvings &&
           same_bits(a.singular_pivot_ratio, b.singular_pivot_ratio) &&
           a.fixed_iterations == b.fixed_iterations;
  }

  // Before a first solve: no determinant sign and no sin/cos anchor of another solve is kept.
  void forget_branch() {
    signs_new_.fill(0);
    trig_ = empty_trig_cache();
  }
  // Whether an angle Newton iterates moved by a turn or more from the q given: the same pose
  // (sin and cos cannot tell), but not the continued value.
  static bool left_turn(const Vector& given, const Vector& q) {
    using std::abs;
    for (const int k : predicted_coordinates())
      if (detail::model_coordinate_kind<Model>(k) == CoordinateKind::kAngle &&
          !(static_cast<double>(abs(q[k] - given[k])) < kTurn))
        return true;
    return false;
  }
  static constexpr double kTurn = 6.283185307179586;

  // The first solve's continuation (detail::first_position on the dense path; spatial headers
  // move the drivers' values instead: detail::continue_drivers), on the block-linear kernels:
  // Newton on Phi(q, t) = (1 - s) Phi(q_given, t), s = 1/n .. 1, each from the last; each block's
  // determinant sign held to the first step's solution's and every angle within half a turn of
  // the step before (Status::kBranchJump). Success leaves q at t's solution, which the ordinary
  // solve refines and checks (n = 1: q unchanged). Nothing is allocated.
  Result continue_first(Vector& q, Scalar t) {
    Result r;
    if constexpr (detail::HasContinuedDrivers<Model>::value) {  // spatial: by the drivers' values
      return detail::continue_drivers<Model>(q, t, dense_.system().params(), dense_.options(),
                                             block_options());
    } else if constexpr (detail::HasBlockFactors<Model>::value) {
      using R = typename Eigen::NumTraits<Scalar>::Real;
      using std::abs;
      constexpr int kNq = Model::nq, kNc = Model::nc, kBlocks = Model::num_blocks;
      constexpr int kNnz = Model::jac_nnz > 0 ? Model::jac_nnz : 1;
      constexpr int kFactors =
          Model::block_factor_begin[kBlocks] > 0 ? Model::block_factor_begin[kBlocks] : 1;
      const Params& p = dense_.system().params();
      Scalar offset[kNc], res[kNc], jac[kNnz], dq[kNq], a[kFactors];
      int piv[kNq];
      // Zeroed: GCC 12 at -O3 cannot see that the first step sets them before they are read.
      signed char start_signs[kBlocks] = {}, signs[kBlocks] = {};
      Model::phi(q.data(), t, p, offset);
      Model::phi_q(q.data(), t, p, jac);
      double best_size[kNc] = {}, best_entry[kNc] = {};
      int best_col[kNc];
      for (int row = 0; row < kNc; ++row) best_col[row] = -1;
      bool finite = q.allFinite();
      for (int e = 0; e < Model::jac_nnz; ++e) {
        const int row = Model::jac_rows[e], col = Model::jac_cols[e];
        const double v = static_cast<double>(abs(jac[e]));
        finite = finite && v - v == 0;
        if (v * detail::model_coordinate_scale<Model>(col) > best_size[row]) {
          best_size[row] = v * detail::model_coordinate_scale<Model>(col);
          best_entry[row] = v;
          best_col[row] = col;
        }
      }
      detail::ContinuationSteps steps(Model::length_scale);
      for (int row = 0; row < kNc; ++row) {
        const double off = static_cast<double>(abs(offset[row]));
        finite = finite && off - off == 0;
        if (best_col[row] >= 0)
          steps.add_row(off, best_entry[row], detail::model_coordinate_kind<Model>(best_col[row]));
      }
      if (!finite || !steps.finite()) {
        r.status = Status::kNonFinite;
        return r;
      }
      const auto o = Model::template _options_as<R>(block_options());
      // Factors every block at q (jac evaluated there) and takes their determinant signs.
      const auto factor = [&](signed char* out) {
        const auto report = Model::template _block_factor_all<Model>(jac, a, piv, o);
        if (report.status != 0) return detail::to_result<Model>(report);
        for (int k = 0; k < kBlocks; ++k) {
          const int b0 = Model::block_begin[k];
          Model::template _with_block_size<Model>(Model::block_begin[k + 1] - b0, [&](auto size) {
            constexpr int K = decltype(size)::value;
            out[k] = static_cast<signed char>(
                Model::template _lu_det_sign<K>(a + Model::block_factor_begin[k], piv + b0));
          });
        }
        return Result{};
      };
      if (steps.count() <= 1) return r;
      if (steps.count() > detail::kMaxContinuationSteps) {
        // A row whose entries vanish needs endless steps: that is a singular Phi_q, so named.
        if (r = factor(signs); !r) return r;
        r.status = Status::kTooFar;
        return r;
      }
      const int n = static_cast<int>(steps.count());
      const R eps = std::numeric_limits<R>::epsilon();
      const R tolerance = R(dense_.options().tolerance);
      for (int i = 1; i <= n; ++i) {
        const Scalar w = Scalar(n - i) / Scalar(n);
        const Vector before = q;
        bool converged = false;
        for (int it = 1; it <= dense_.options().max_iterations && !converged; ++it) {
          Model::phi(q.data(), t, p, res);
          for (int row = 0; row < kNc; ++row) res[row] -= w * offset[row];
          if (i > 1 || it > 1) Model::phi_q(q.data(), t, p, jac);
          if (r = factor(signs); !r) return r;
          if (!Model::template _block_forward_factored<Model>(jac, a, piv, res, dq, 1)) {
            r.status = Status::kNonFinite;
            return r;
          }
          converged = true;
          for (int k = 0; k < kNq; ++k) {
            const R scale = R(detail::model_coordinate_scale<Model>(k));
            q[k] -= dq[k];
            converged =
                converged && kernels::NewtonKernel::_step_converged(
                                 R(abs(dq[k])) / scale, R(abs(q[k])) / scale, tolerance, eps);
          }
          r.iterations = std::max(r.iterations, it);
        }
        if (!q.allFinite()) {
          r.status = Status::kNonFinite;
          return r;
        }
        if (!converged) {
          r.status = Status::kMaxIterations;
          return r;
        }
        for (int k = 0; k < kBlocks; ++k) {
          if (i == 1) start_signs[k] = signs[k];
          if (signs[k] != start_signs[k]) {
            r.status = Status::kBranchJump;
            r.block = k;
            return r;
          }
        }
        for (int k = 0; k < kNq; ++k) {
          if (detail::model_coordinate_kind<Model>(k) == CoordinateKind::kAngle &&
              !(static_cast<double>(abs(q[k] - before[k])) < kTurn / 2)) {
            r.status = Status::kBranchJump;
            return r;
          }
        }
      }
    }
    return r;
  }

  auto block_options() const {
    return block_options_from<typename Model::BlockOptions>(dense_.options());
  }

  // The generated position and full-step solves, with the sin/cos cache and the blocks'
  // determinant signs where the header takes them.
  template <class O>
  Result solve_block_position(Vector& q, Scalar t, const O& o) {
    const auto& p = dense_.system().params();
    if constexpr (kSigns) {
      return detail::to_result<Model>(
          Model::solve_position(q.data(), t, p, o, trig_.data(), signs_new_.data()));
    } else if constexpr (kTrigCache > 0) {
      return detail::to_result<Model>(Model::solve_position(q.data(), t, p, o, trig_.data()));
    } else {
      return detail::to_result<Model>(Model::solve_position(q.data(), t, p, o));
    }
  }
  template <class O>
  Result solve_block_step(Vector& q, Scalar t, Vector& qd, Vector& qdd, const O& o) {
    const auto& p = dense_.system().params();
    if constexpr (kStepFactors) {
      return detail::to_result<Model>(Model::solve_step(
          q.data(), t, p, qd.data(), qdd.data(), o, trig_.data(), signs_new_.data(), &factors_));
    } else if constexpr (kSigns) {
      return detail::to_result<Model>(Model::solve_step(q.data(), t, p, qd.data(), qdd.data(), o,
                                                        trig_.data(), signs_new_.data()));
    } else if constexpr (kTrigCache > 0) {
      return detail::to_result<Model>(
          Model::solve_step(q.data(), t, p, qd.data(), qdd.data(), o, trig_.data()));
    } else {
      return detail::to_result<Model>(Model::solve_step(q.data(), t, p, qd.data(), qdd.data(), o));
    }
  }
  // What the dense path checks after its Newton loop, for a block solve: the residual (from
  // the report where the kernels measured it, else from Model::phi here) against
  // residual_tolerance, and the condition against min_rcond where the kernels estimated it. A
  // fixed iteration budget that leaves the constraints open is kBudgetExhausted.
  Result checked(const Vector& q, Scalar t, Result r) {
    if (r.status != Status::kConverged) return r;
    const SolverOptions& s = dense_.options();
    using Report = decltype(Model::solve_position(std::declval<Scalar*>(), Scalar(0),
                                                  std::declval<const Params&>(),
                                                  std::declval<typename Model::BlockOptions>()));
    // Headers whose kernels measure the residual have already checked it and the condition,
    // against these options plus the scalar's rounding allowance (kernels/newton.hpp).
    if constexpr (detail::ReportHasResidual<Report>::value) return r;
    r.residual = detail::model_residual<Model>(q.data(), t, dense_.system().params());
    if (!(r.residual <= s.residual_tolerance)) {
      r.status = !(r.residual == r.residual) ? Status::kNonFinite
                 : s.fixed_iterations > 0    ? Status::kBudgetExhausted
                                             : Status::kInconsistent;
    } else if (r.condition * s.min_rcond > 1) {  // NaN (not estimated) passes
      r.status = Status::kSingular;
    }
    return r;
  }
  // Whether a block's determinant changed sign since the last step (headers that report them).
  bool signs_changed() const {
    for (std::size_t b = 0; b < signs_.size(); ++b)
      if (kSigns && signs_[b] != 0 && signs_new_[b] != 0 && signs_[b] != signs_new_[b]) return true;
    return false;
  }

  // Calls f(k) for each coordinate the predictor extrapolates: those Newton iterates when the
  // header lists them (the block solver computes every other one from them), otherwise all.
  // The jump test compares the same ones: an explicit block has one solution given the blocks
  // before it, so only a Newton block can change branch.
  static constexpr const auto& predicted_coordinates() {
    if constexpr (kBlockSolver && detail::HasNewtonCoordinates<Model>::value) {
      return Model::newton_coordinates;
    } else {
      return kAllCoordinates;
    }
  }
  template <class F>
  static void for_predicted(F&& f) {
    for (const int k : predicted_coordinates()) f(k);
  }
  static constexpr std::array<int, Model::nq> kAllCoordinates = [] {
    std::array<int, Model::nq> a{};
    for (int k = 0; k < Model::nq; ++k) a[k] = k;
    return a;
  }();
  // The block solver needs no dense workspace (none of nq x nq is ever formed).
  struct NoDense {
    NoDense() = default;
    NoDense(const Params& params, SolverOptions options) : system_(params), options_(options) {}
    const GeneratedSystem<Model, Scalar>& system() const { return system_; }
    GeneratedSystem<Model, Scalar>& system() { return system_; }
    const SolverOptions& options() const { return options_; }
    SolverOptions& options() { return options_; }
    GeneratedSystem<Model, Scalar> system_;
    SolverOptions options_;
  };
  std::conditional_t<kBlockSolver, NoDense, DenseSolver<Model, Scalar>> dense_;

  static constexpr Scalar kNaN = std::numeric_limits<Scalar>::quiet_NaN();
  // The factors of the last step's rate solve (headers whose solve_step keeps them), valid
  // after a successful step() until the next step() or reset(), for forces() at its t and q.
  static constexpr bool kStepFactors = kForces && detail::HasStepFactors<Model>::value;
  typename detail::StepFactorsOf<Model, Scalar>::type factors_{};
  bool factors_valid_ = false;
  Scalar t_factored_ = Scalar(0);
  Vector q_factored_ = Vector::Zero();
  Params params_factored_{};
  SolverOptions options_factored_{};
  // Whether a solve succeeded since construction or reset(): until then a solve is a first
  // solve, by continuation from the q given.
  bool assembled_ = false;
  // The generated sin/cos cache: anchors with their exact sin and cos, NaN when empty, so that
  // a step near the last one rotates instead of calling sin and cos.
  static constexpr int kTrigCache = kBlockSolver ? detail::TrigCacheSize<Model>::value : 0;
  static std::array<Scalar, (kTrigCache > 0 ? kTrigCache : 1)> empty_trig_cache() {
    std::array<Scalar, (kTrigCache > 0 ? kTrigCache : 1)> a;
    a.fill(kNaN);
    return a;
  }
  std::array<Scalar, (kTrigCache > 0 ? kTrigCache : 1)> trig_ = empty_trig_cache();
  // Whether solve_position and solve_step take the blocks' determinant signs.
  template <class M, class = void>
  struct TakesSigns : std::false_type {};
  template <class M>
  struct TakesSigns<M, std::void_t<decltype(M::solve_position(
                           std::declval<Scalar*>(), Scalar(0), std::declval<const Params&>(),
                           std::declval<const typename M::BlockOptions&>(), std::declval<Scalar*>(),
                           std::declval<signed char*>()))>>
      : std::bool_constant<(detail::NumBlocks<M>::value > 0)> {};
  static constexpr bool kSigns = [] {
    if constexpr (kBlockSolver) {
      return TakesSigns<Model>::value;
    } else {
      return false;
    }
  }();
  static constexpr int kNumSigns = kSigns ? detail::NumBlocks<Model>::value : 1;
  std::array<signed char, kNumSigns> signs_{}, signs_new_{};
  Scalar t_previous_ = Scalar(0);
  bool has_previous_ = false, has_two_ = false;
  Scalar h_previous_ = Scalar(0);
  // The last solved step (the jump test's start) and the acceleration one step before it
  // (the predictor's jerk; zero before, where the predictor does not read it).
  Vector q_previous_ = Vector::Zero(), qd_previous_ = Vector::Zero(),
         qdd_previous_ = Vector::Zero(), qdd_before_ = Vector::Zero();
  // What a failed step() in sub-steps puts back, and where it failed.
  struct History {
    Scalar t, h;
    bool has_two;
    Vector q, qd, qdd, qdd_before;
    std::array<signed char, kNumSigns> signs, signs_new;
  };
  Scalar failed_at_ = Scalar(0);
};

}  // namespace kinegen
