// kinegen::Solver: drives a generated model's block solver (position, velocity and
// acceleration block by block in block-lower-triangular order, see docs/performance.md) when
// the header has one, and falls back to DenseSolver otherwise. Adds a full step with a Taylor
// predictor. Header-only, Eigen and std only, allocation-free.
#pragma once

#include <array>
#include <limits>
#include <type_traits>

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

template <class Report>
Result to_result(const Report& report) {
  Result r;
  r.status = static_cast<Status>(report.status);
  r.iterations = report.iterations;
  r.step = report.step;
  if (r.status == Status::kSingular) r.pivot_ratio = 0;
  return r;
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

  Solver() = default;
  explicit Solver(const Params& params, SolverOptions options = {}) : dense_(params, options) {}

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
  // Result::iterations is the largest count of any block.
  Result position(Vector& q, Scalar t) {
    if constexpr (kBlockSolver) {
      if constexpr (kTrigCache > 0) {
        return detail::to_result(Model::solve_position(q.data(), t, dense_.system().params(),
                                                       block_options(), trig_.data()));
      } else {
        return detail::to_result(
            Model::solve_position(q.data(), t, dense_.system().params(), block_options()));
      }
    } else {
      return dense_.position(q, t);
    }
  }
  // Solves Phi_q qd = nu at a solved q.
  Result velocity(const Vector& q, Scalar t, Vector& qd) {
    if constexpr (kBlockSolver) {
      const Result r = detail::to_result(
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
      const Result r = detail::to_result(Model::solve_acceleration(
          q.data(), qd.data(), t, dense_.system().params(), qdd.data(), block_options()));
      if (!r) qdd.setConstant(kNaN);
      return r;
    } else {
      return dense_.acceleration(q, qd, t, qdd);
    }
  }

  // One full step at time t: q is predicted from the previous step's q, qd and qdd (Taylor
  // over h = t - t_previous, with the jerk estimated from the last two accelerations; none on
  // the first call or after reset()), then solved, then qd and qdd. q, qd and qdd are the
  // caller's state, passed back unchanged between steps (call reset() after changing them).
  Result step(Scalar t, Vector& q, Vector& qd, Vector& qdd) {
    const Scalar h = has_previous_ ? t - t_previous_ : Scalar(0);
    if (has_previous_) {
      // Third order: the jerk from the last two accelerations. The prediction error is then
      // O(h^4), below the tolerance at small steps, so one iteration converges.
      const Scalar h2 = h * h / Scalar(2);
      const Scalar h3 =
          has_two_ && h_previous_ != Scalar(0) ? h * h * h / (Scalar(6) * h_previous_) : Scalar(0);
      for_predicted([&](int k) {  // one pass (Eigen would make three)
        q[k] += h * qd[k] + h2 * qdd[k] + h3 * (qdd[k] - qdd_previous_[k]);
      });
    }
    for_predicted([&](int k) { qdd_last_[k] = qdd[k]; });
    // Without a prediction the first solve iterates to convergence even when the options fix
    // the iteration count.
    if constexpr (kBlockSolver && detail::HasAcceleration<Model>::value) {
      auto o = block_options();
      if (!has_previous_) o.fixed_iterations = 0;
      Result r;
      if constexpr (kTrigCache > 0) {
        r = detail::to_result(Model::solve_step(q.data(), t, dense_.system().params(), qd.data(),
                                                qdd.data(), o, trig_.data()));
      } else {
        r = detail::to_result(
            Model::solve_step(q.data(), t, dense_.system().params(), qd.data(), qdd.data(), o));
      }
      if (!r) {
        qd.setConstant(kNaN);
        qdd.setConstant(kNaN);
        return r;
      }
      advance(t, h);
      return r;
    } else {
      const Result r = position(q, t);
      if (!r) return r;
      if (const Result rv = velocity(q, t, qd); !rv) return rv;
      if (const Result ra = acceleration(q, qd, t, qdd); !ra) return ra;
      advance(t, h);
      return r;
    }
  }
  // Forgets the previous step: the next step() starts Newton from the q given.
  void reset() { has_previous_ = has_two_ = false; }

 private:
  auto block_options() const {
    typename Model::BlockOptions o;
    const SolverOptions& s = dense_.options();
    o.tolerance = s.tolerance;
    o.max_iterations = s.max_iterations;
    o.fixed_iterations = s.fixed_iterations;
    o.singular_pivot_ratio = s.singular_pivot_ratio;
    return o;
  }

  // Calls f(k) for each coordinate the predictor extrapolates: those Newton iterates when the
  // header lists them (the block solver computes every other one from them), otherwise all.
  template <class F>
  static void for_predicted(F&& f) {
    if constexpr (kBlockSolver && detail::HasNewtonCoordinates<Model>::value) {
      for (int k : Model::newton_coordinates) f(k);
    } else {
      for (int k = 0; k < Model::nq; ++k) f(k);
    }
  }
  void advance(Scalar t, Scalar h) {
    has_two_ = has_previous_;
    h_previous_ = h;
    for_predicted([&](int k) { qdd_previous_[k] = qdd_last_[k]; });
    t_previous_ = t;
    has_previous_ = true;
  }

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
  // The generated sin/cos cache: anchors with their exact sin and cos, NaN when empty, so that
  // a step near the last one rotates instead of calling sin and cos.
  static constexpr int kTrigCache = kBlockSolver ? detail::TrigCacheSize<Model>::value : 0;
  static std::array<Scalar, (kTrigCache > 0 ? kTrigCache : 1)> empty_trig_cache() {
    std::array<Scalar, (kTrigCache > 0 ? kTrigCache : 1)> a;
    a.fill(kNaN);
    return a;
  }
  std::array<Scalar, (kTrigCache > 0 ? kTrigCache : 1)> trig_ = empty_trig_cache();
  Scalar t_previous_ = Scalar(0);
  bool has_previous_ = false, has_two_ = false;
  Scalar h_previous_ = Scalar(0);
  // The caller's qdd at the last and the previous step (zero before: the predictor multiplies
  // the difference by 0 then, and must not meet uninitialized values).
  Vector qdd_last_ = Vector::Zero(), qdd_previous_ = Vector::Zero();
};

}  // namespace kinegen
