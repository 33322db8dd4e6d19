// kinegen::Solver: drives a generated model's block solver (position, velocity and
// acceleration block by block in block-lower-triangular order, see docs/performance.md) when
// the header has one, and falls back to DenseSolver otherwise. Adds a full step with a Taylor
// predictor. Header-only, Eigen and std only, allocation-free.
#pragma once

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
class Solver : public DenseSolver<Model, Scalar> {
  using Base = DenseSolver<Model, Scalar>;

 public:
  using Params = typename Model::Params;
  using typename Base::Vector;
  // True when the generated block functions are used; false: dense Newton on Phi_q.
  static constexpr bool kBlockSolver = detail::HasBlockSolver<Model>::value;

  Solver() = default;
  explicit Solver(const Params& params, SolverOptions options = {}) : Base(params, options) {}

  // Newton from the q given; q is overwritten with the solution (or the last iterate).
  // Result::iterations is the largest count of any block.
  Result position(Vector& q, Scalar t) {
    if constexpr (kBlockSolver) {
      return detail::to_result(
          Model::solve_position(q.data(), t, this->system().params(), block_options()));
    } else {
      return Base::position(q, t);
    }
  }
  // Solves Phi_q qd = nu at a solved q.
  Result velocity(const Vector& q, Scalar t, Vector& qd) {
    if constexpr (kBlockSolver) {
      const Result r = detail::to_result(
          Model::solve_velocity(q.data(), t, this->system().params(), qd.data(), block_options()));
      if (!r) qd.setConstant(kNaN);  // no stale or partial values after a failure
      return r;
    } else {
      return Base::velocity(q, t, qd);
    }
  }
  // Solves Phi_q qdd = gamma at a solved q and qd.
  Result acceleration(const Vector& q, const Vector& qd, Scalar t, Vector& qdd) {
    if constexpr (kBlockSolver) {
      const Result r = detail::to_result(Model::solve_acceleration(
          q.data(), qd.data(), t, this->system().params(), qdd.data(), block_options()));
      if (!r) qdd.setConstant(kNaN);
      return r;
    } else {
      return Base::acceleration(q, qd, t, qdd);
    }
  }

  // One full step at time t: q is predicted from the previous step's q, qd and qdd (a
  // second-order Taylor step over t - t_previous; none on the first call or after reset()),
  // then solved, then qd and qdd. q, qd and qdd are the caller's state, passed back each step.
  Result step(Scalar t, Vector& q, Vector& qd, Vector& qdd) {
    if (has_previous_) {
      const Scalar h = t - t_previous_;
      q += h * qd + (h * h / Scalar(2)) * qdd;
    }
    // Without a prediction the first solve iterates to convergence even when the options fix
    // the iteration count.
    if constexpr (kBlockSolver && detail::HasAcceleration<Model>::value) {
      auto o = block_options();
      if (!has_previous_) o.fixed_iterations = 0;
      const Result r = detail::to_result(
          Model::solve_step(q.data(), t, this->system().params(), qd.data(), qdd.data(), o));
      if (!r) {
        qd.setConstant(kNaN);
        qdd.setConstant(kNaN);
        return r;
      }
      t_previous_ = t;
      has_previous_ = true;
      return r;
    } else {
      const Result r = position(q, t);
      if (!r) return r;
      if (const Result rv = velocity(q, t, qd); !rv) return rv;
      if (const Result ra = acceleration(q, qd, t, qdd); !ra) return ra;
      t_previous_ = t;
      has_previous_ = true;
      return r;
    }
  }
  // Forgets the previous step: the next step() starts Newton from the q given.
  void reset() { has_previous_ = false; }

 private:
  auto block_options() const {
    typename Model::BlockOptions o;
    const SolverOptions& s = this->options();
    o.tolerance = s.tolerance;
    o.max_iterations = s.max_iterations;
    o.fixed_iterations = s.fixed_iterations;
    o.singular_pivot_ratio = s.singular_pivot_ratio;
    return o;
  }

  static constexpr Scalar kNaN = std::numeric_limits<Scalar>::quiet_NaN();
  Scalar t_previous_ = Scalar(0);
  bool has_previous_ = false;
};

}  // namespace kinegen
