// kinegen runtime: forward dynamics of a generated model at a fixed step, for a
// control loop. Simulator<Model, T> steps the header's dynamics() (the minimal coordinates'
// zdd, what `kinegen simulate` computes) with the integrator kernel (kernels/integrate.hpp):
// the classical Runge-Kutta step, or the L-stable SDIRK2 for stiff springs, its Newton on the
// header's exact dynamics_jacobians where it has them (forward differences otherwise).
// Nothing is allocated: the state and the header's work space live in the object.
#pragma once

#include <type_traits>

#include "kinegen/block_solver.hpp"
#include "kinegen/kernels/integrate.hpp"

namespace kinegen {

namespace detail {

template <class Model, class = void>
struct HasDynamicsJacobians : std::false_type {};
template <class Model>
struct HasDynamicsJacobians<Model, std::void_t<decltype(Model::has_dynamics_jacobians)>>
    : std::bool_constant<Model::has_dynamics_jacobians> {};

}  // namespace detail

// Which step Simulator::step takes.
enum class Integrator {
  kRungeKutta4,  // explicit, order 4: 4 dynamics() per step; stable for h w < 2.8
  kImplicit,     // SDIRK2, L-stable, order 2: stiff springs at any h; Newton per stage
};

struct SimulatorOptions {
  Integrator integrator = Integrator::kRungeKutta4;
  // The implicit step's Newton on each stage: at most this many iterations, until the update
  // (angles in radians, lengths over the model's length_scale, rates likewise per second) is
  // at most newton_tolerance; 0: the scalar's position tolerance (BasicBlockOptions: double
  // 1.2e-10, float 3.1e-5).
  int newton_iterations = 10;
  double newton_tolerance = 0;
};

template <class Model, class T = double>
class Simulator {
 public:
  static constexpr int nf = Model::nf;
  static constexpr int kStates = 2 * nf;  // x = (z, zd)
  using Params = typename Model::Params;
  using Real = typename Eigen::NumTraits<T>::Real;
  // Whether the implicit step's Newton uses the header's exact Jacobians.
  static constexpr bool kExactJacobians = detail::HasDynamicsJacobians<Model>::value;

  // solver: the position solves' options (default_options<T>(): tolerances of T's precision).
  explicit Simulator(const Params& params = Params{}, SimulatorOptions options = {},
                     SolverOptions solver = default_options<T>())
      : params_(params), options_(options) {
    block_ = block_options_from<decltype(block_)>(solver);
    for (int k = 0; k < kStates; ++k) x_[k] = xd_[k] = T(0);
    for (int k = 0; k < nf; ++k) scale_[k] = scale_[nf + k] = Real(Model::free_scale(k));
  }

  // Starts a motion at (t, z, zd): the position solve from the file's q0 (or, with keep_q,
  // from the current q), and the accelerations there.
  Result reset(T t, const T* z, const T* zd, bool keep_q = false) {
    if (!keep_q) {
      work_.reset();
      clear(jacobian_work_, 0);
    }
    t_ = t;
    for (int k = 0; k < nf; ++k) {
      x_[k] = z[k];
      x_[nf + k] = zd[k];
    }
    return evaluate();
  }

  // Advances the motion by h with the integrator of the options. On failure the state, q and
  // the accelerations stay those before the step; the Result says why.
  Result step(T h) {
    T saved[kStates], saved_rate[kStates];
    for (int k = 0; k < kStates; ++k) {
      saved[k] = x_[k];
      saved_rate[k] = xd_[k];
    }
    const typename Model::template DynamicsWork<T> before = work_;
    const T t0 = t_;
    first_ = !dirty_;  // the state's rate is known unless the Params changed since
    dirty_ = false;
    const auto f = [this](T t, const T* x, T* xd) { return rhs(t, x, xd); };
    int status = 0;
    if (options_.integrator == Integrator::kRungeKutta4) {
      status = kernels::IntegrateKernel::_rk4_step<kStates>(t_, h, x_, f);
    } else {
      const auto jac = [this, &f](T t, const T* x, const T* fx, T* j) {
        return jacobian(t, x, fx, j, f);
      };
      status = kernels::IntegrateKernel::_sdirk2_step<kStates>(
          t_, h, x_, scale_, f, jac, options_.newton_iterations, newton_tolerance(),
          &newton_iterations_);
    }
    if (status == 0) {
      t_ += h;
      const Result r = evaluate();
      if (r) return r;
      status = static_cast<int>(r.status);
    }
    for (int k = 0; k < kStates; ++k) {
      x_[k] = saved[k];
      xd_[k] = saved_rate[k];
    }
    t_ = t0;
    work_ = before;
    Result r;
    r.status = static_cast<Status>(status);
    r.block = last_.block;
    return r;
  }

  T time() const { return t_; }
  const T* z() const { return x_; }
  const T* zd() const { return x_ + nf; }
  const T* zdd() const { return xd_ + nf; }
  // The full coordinates at the state: q, qd, qdd (dynamics()' work space).
  const T* q() const { return work_.q; }
  const T* qd() const { return work_.qd; }
  const T* qdd() const { return work_.qdd; }
  // The Params (inputs u included) for the next steps; the next step evaluates anew.
  Params& params() {
    dirty_ = true;
    return params_;
  }
  const Params& params() const { return params_; }
  const SimulatorOptions& options() const { return options_; }
  SimulatorOptions& options() { return options_; }
  // The implicit step's Newton iterations over both stages of the last step.
  int newton_iterations() const { return newton_iterations_; }

 private:
  // x' = (zd, zdd) at (t, x); the first call of a step is at the state, whose zdd is known.
  int rhs(T t, const T* x, T* xd) {
    if (first_) {
      first_ = false;
      for (int k = 0; k < kStates; ++k) xd[k] = xd_[k];
      return 0;
    }
    for (int k = 0; k < nf; ++k) xd[k] = x[nf + k];
    last_ = Model::dynamics(x, x + nf, t, params_, xd + nf, block_, work_);
    return last_.status;
  }

  template <class F>
  int jacobian(T t, const T* x, const T* fx, T* j, F& f) {
    if constexpr (kExactJacobians) {
      T dz[nf * nf], dzd[nf * nf], zdd[nf];
      last_ = Model::dynamics_jacobians(x, x + nf, t, params_, zdd, dz, dzd,
                                        static_cast<T*>(nullptr), block_, work_, jacobian_work_);
      if (last_.status != 0) return last_.status;
      kernels::IntegrateKernel::_state_jacobian<nf>(dz, dzd, j);
      (void)fx;
      (void)f;
      return 0;
    } else {
      first_ = false;
      return kernels::IntegrateKernel::_difference_jacobian<kStates>(t, x, fx, scale_, j, f);
    }
  }

  Real newton_tolerance() const {
    if (options_.newton_tolerance > 0) return Real(options_.newton_tolerance);
    return typename Model::template BasicBlockOptions<Real>().tolerance;
  }

  Result evaluate() {
    dirty_ = false;
    for (int k = 0; k < nf; ++k) xd_[k] = x_[nf + k];
    last_ = Model::dynamics(x_, x_ + nf, t_, params_, xd_ + nf, block_, work_);
    return detail::to_result<Model>(last_);
  }

  Params params_;
  SimulatorOptions options_;
  typename Model::BlockOptions block_;
  typename Model::template DynamicsWork<T> work_;
  struct NoWork {};
  template <class M, bool kExact = kExactJacobians>
  struct JacobianWorkOf {
    using type = NoWork;
  };
  template <class M>
  struct JacobianWorkOf<M, true> {
    using type = typename M::template JacobianWork<T>;
  };
  typename JacobianWorkOf<Model>::type jacobian_work_;
  // Empties a JacobianWork's sin/cos cache (headers from before it had one: nothing to do).
  template <class W>
  static auto clear(W& w, int) -> decltype(w.reset(), void()) {
    w.reset();
  }
  template <class W>
  static void clear(W&, long) {}
  typename Model::template BlockReport<Real> last_;
  T t_ = T(0);
  T x_[kStates], xd_[kStates];  // the state and its rate at t_
  Real scale_[kStates];
  bool first_ = false, dirty_ = true;
  int newton_iterations_ = 0;
};

}  // namespace kinegen
