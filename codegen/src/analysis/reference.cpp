// The 40-digit reference (reference.hpp): the analysis in CLN arithmetic at D digits, with the
// runtime's Newton policy, and its forces (ReferenceForces).
#include "kinegen/codegen/analysis/reference.hpp"

#include <cln/cln.h>

#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>

#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/kinematics.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"
#include "kinegen/kernels/newton.hpp"
#include "kinegen/solver.hpp"
#include "numeric_lu.hpp"

namespace kinegen::codegen {

using GiNaC::ex;
using GiNaC::numeric;
using Vector = HighPrecisionEvaluator::Vector;
using Lu = analysis_detail::NumericLu;

struct ReferenceForces::Data {
  ForceData<numeric> numbers;
  numeric pivot_ratio;
};

ReferenceForces::ReferenceForces(const CompiledModel& model, const ForceModel& forces, int digits)
    : model_(&model),
      forces_(&forces),
      eval_(std::make_unique<HighPrecisionEvaluator>(model, digits)),
      data_(std::make_unique<Data>()) {
  if (model.nc() != model.nq())
    throw UsageError("--forces needs as many independent equations as coordinates (" +
                     std::to_string(model.nc()) + " equations, " + std::to_string(model.nq()) +
                     " coordinates): the reactions of redundant constraints are not unique");
  applied_ = eval_->add_outputs(forces.applied);
  const DigitsGuard guard(digits);
  const auto value = [&](const ex& e) {
    return eval_->to_float(GiNaC::ex_to<numeric>(GiNaC::evalf(e)));
  };
  const auto values = [&](const std::vector<ex>& v) {
    std::vector<numeric> r;
    for (const ex& e : v) r.push_back(value(e));
    return r;
  };
  const auto pairs = [&](const std::vector<std::array<ex, 2>>& v) {
    std::vector<std::array<numeric, 2>> r;
    for (const auto& e : v) r.push_back({value(e[0]), value(e[1])});
    return r;
  };
  data_->numbers = {values(forces.exact.mass), values(forces.exact.inertia),
                    pairs(forces.exact.com), pairs(forces.exact.si), pairs(forces.exact.sj)};
  data_->pivot_ratio = numeric(10).power(-(digits - 3));
}

ReferenceForces::~ReferenceForces() = default;

std::vector<numeric> ReferenceForces::solve(const ReferenceRow& row) {
  const DigitsGuard guard(eval_->digits());
  const int nq = model_->nq();
  const auto& sym = model_->symbolic();
  std::vector<numeric> jac(static_cast<std::size_t>(nq) * nq, numeric(0)), transposed = jac;
  const Vector values = eval_->phi_q_values(row.q, row.t);
  for (std::size_t k = 0; k < values.size(); ++k) {
    jac[sym.phi_q[k].row * nq + sym.phi_q[k].col] = values[k];
    transposed[sym.phi_q[k].col * nq + sym.phi_q[k].row] = values[k];
  }
  Vector q_total = eval_->evaluate(applied_, row.q, row.qd, row.t);
  add_inertia_forces(data_->numbers, static_cast<int>(model_->mechanism().bodies.size()),
                     row.q.data(), row.qd.data(), row.qdd.data(), q_total.data());
  Lu lu;
  if (!lu.factor(transposed, nq, data_->pivot_ratio))
    throw AnalysisError(model_->mechanism().source + ": --forces: Phi_q is singular at " +
                        format_time(row.t.to_double()) + " (reference)");
  const Vector lambda = lu.solve(q_total);
  std::vector<numeric> columns;
  columns_from_lambda(model_->mechanism(), *forces_, data_->numbers, row.q.data(), jac, lambda,
                      columns);
  return columns;
}

StateRow to_state_row(const ReferenceRow& row) {
  StateRow s;
  s.t = row.t.to_double();
  const auto vec = [](const std::vector<numeric>& v) {
    Eigen::VectorXd d(v.size());
    for (std::size_t k = 0; k < v.size(); ++k) d[k] = v[k].to_double();
    return d;
  };
  s.q = vec(row.q);
  s.qd = vec(row.qd);
  s.qdd = vec(row.qdd);
  for (const auto& p : row.points) {
    PointState ps;
    ps.r = {p[0].to_double(), p[1].to_double()};
    ps.v = {p[2].to_double(), p[3].to_double()};
    ps.a = {p[4].to_double(), p[5].to_double()};
    s.points.push_back(ps);
  }
  for (std::size_t o = 0; o < row.outputs.size(); ++o) {
    const auto& r = row.outputs[o];
    // An output that reads velocities has no acceleration (format: nan).
    const bool none = o < row.velocity_outputs.size() && row.velocity_outputs[o];
    s.outputs.push_back({r[0].to_double(), r[1].to_double(),
                         none ? std::numeric_limits<double>::quiet_NaN() : r[2].to_double()});
  }
  return s;
}

namespace {

// The reference's time loop at `digits` digits: Newton on all of Phi_q with the runtime's
// policy (kernels/newton.hpp) at eps = 10^-digits, then the rates, points and outputs.
class ReferenceRun {
 public:
  ReferenceRun(const CompiledModel& model, int digits)
      : model_(model),
        digits_(digits),
        eval_(model, digits),
        nq_(model.nq()),
        file_(model.mechanism().source),
        sym_(model.symbolic()) {
    // The Newton policy of the runtime (kernels/newton.hpp) with eps = 10^-digits. Newton
    // converges quadratically, so a step of 10^-(digits-5) (plus the rounding allowance)
    // leaves an error far below the working precision; near it, rounding noise of
    // cond(Phi_q) 10^-digits could keep the step from falling further, so a step that stops
    // decreasing below 10^-(digits/2) ends it (_stalled). The residual is then rechecked
    // against 10^-(digits/2), as the double paths check 2^-(53/2). Phi_q's singularity is
    // judged by the LU's pivots (no condition estimate here, so no linear-convergence rule).
    const numeric ten = 10;
    eps_ = ten.power(-digits);
    tolerance_ = ten.power(-(digits - 5));
    stagnation_ = ten.power(-(digits / 2));
    residual_tolerance_ = stagnation_;
    pivot_ratio_ = ten.power(-(digits - 3));
    for (double scale : sym_.coordinate_scales)
      inv_scale_.push_back(eval_.to_float(numeric(1) / exact_numeric(scale)));
    // Point offsets, exact parameters substituted.
    for (const auto& [x, y] : sym_.point_s) {
      const auto value = [&](const ex& e) {
        return eval_.to_float(GiNaC::ex_to<numeric>(
            GiNaC::evalf(substitute_params(e, model.symbols(), sym_.param_values))));
      };
      offsets_.push_back({value(x), value(y)});
    }
    // Outputs: values, then rates, a0 and O_q (output_rate_expressions), in one tape.
    num_outputs_ = static_cast<int>(sym_.output_values.size());
    if (num_outputs_ > 0) {
      std::vector<ex> all = sym_.output_values;
      for (const ex& e : output_rate_expressions(sym_)) all.push_back(e);
      output_tape_ = eval_.add_outputs(all);
    }
  }

  void run(const TimeGrid& grid, const std::function<void(const ReferenceRow&)>& sink) {
    const Eigen::VectorXd q0 = model_.q0();
    for (int k = 0; k < nq_; ++k) row_.q.push_back(eval_.to_float(exact_numeric(q0[k])));
    row_.qd.assign(nq_, numeric(0));
    row_.qdd.assign(nq_, numeric(0));
    for (int step = 0; step <= grid.steps; ++step) {
      td_ = grid.at(step);
      const numeric t = eval_.to_float(exact_numeric(td_));
      try {
        if (step > 0) {
          const numeric h = t - row_.t;
          const numeric half_h2 = h * h / 2;
          for (int k = 0; k < nq_; ++k)
            row_.q[k] = row_.q[k] + h * row_.qd[k] + half_h2 * row_.qdd[k];
        }
        row_.t = t;
        const bool converged = solve_position(t);
        // The residual recheck, on the Jacobian the velocity and acceleration then share.
        const std::vector<numeric> a = jacobian(row_.q, t);
        const numeric residual = converged ? scaled_residual(a, t) : numeric(0);
        const int status = Newton::_newton_status(false, converged, residual <= residual_tolerance_,
                                                  false, residual, numeric(1), numeric(0));
        if (status == static_cast<int>(Status::kMaxIterations))
          fail("position", "Newton iteration did not converge in " +
                               std::to_string(kMaxIterations) +
                               " iterations; the mechanism may not assemble here");
        if (status != 0) fail("position", kinegen::to_string(static_cast<Status>(status)));
        // Velocity and acceleration share one factorization at the solved position.
        if (!lu_.factor(a, nq_, pivot_ratio_))
          fail("velocity", "the constraint Jacobian Phi_q is singular");
        row_.qd = lu_.solve(eval_.nu(row_.q, t));
        row_.qdd = lu_.solve(eval_.gamma(row_.q, row_.qd, t));
      } catch (const AnalysisError& e) {
        const std::string what = e.what();
        if (what.rfind(file_ + ": ", 0) == 0) throw;
        fail("position", what);
      }
      complete_row(t);
      sink(row_);
      interruption_point();
    }
  }

 private:
  using Newton = kernels::NewtonKernel;
  static constexpr int kMaxIterations = 60;

  [[noreturn]] void fail(const std::string& stage, const std::string& why) const {
    throw AnalysisError(file_ + ": reference " + stage + " analysis (" + std::to_string(digits_) +
                        " digits) failed at " + format_time(td_) + ": " + why);
  }

  std::vector<numeric> jacobian(const Vector& q, const numeric& t) {
    std::vector<numeric> a(static_cast<std::size_t>(nq_) * nq_, numeric(0));
    const Vector values = eval_.phi_q_values(q, t);
    for (std::size_t k = 0; k < values.size(); ++k)
      a[sym_.phi_q[k].row * nq_ + sym_.phi_q[k].col] = values[k];
    return a;
  }

  // Newton from row_.q; whether the step criterion (or the stall test) ended it.
  bool solve_position(const numeric& t) {
    numeric last_step = 0;  // 0: no step yet
    bool converged = false;
    int it = 1;
    for (; it <= kMaxIterations && !converged; ++it) {
      const Vector f = eval_.phi(row_.q, t);
      if (!lu_.factor(jacobian(row_.q, t), nq_, pivot_ratio_))
        fail("position", "the constraint Jacobian Phi_q is singular");
      const Vector dq = lu_.solve(f);
      numeric size = 0;
      bool small = true;
      for (int k = 0; k < nq_; ++k) {
        row_.q[k] = row_.q[k] - dq[k];
        const numeric d = GiNaC::abs(dq[k] * inv_scale_[k]);
        size = std::max(size, d);
        small = small &&
                Newton::_step_converged(d, GiNaC::abs(row_.q[k] * inv_scale_[k]), tolerance_, eps_);
      }
      converged = small || Newton::_stalled(size, last_step, stagnation_);
      last_step = size;
    }
    row_.newton_iterations = it - 1;
    return converged;
  }

  // The largest scaled residual less its rounding allowance (rows scaled as on the double
  // paths: by their largest |entry| times the column's scale).
  numeric scaled_residual(const std::vector<numeric>& a, const numeric& t) {
    numeric residual = 0;
    const Vector f = eval_.phi(row_.q, t);
    for (int r = 0; r < nq_; ++r) {
      numeric size = 0, terms = 0;
      for (int k = 0; k < nq_; ++k) {
        const numeric v = GiNaC::abs(a[r * nq_ + k]);
        if (v.is_zero()) continue;
        size = std::max(size, v / inv_scale_[k]);
        terms = terms + v * GiNaC::abs(row_.q[k]);
      }
      if (size.is_zero()) size = 1;
      residual = std::max(residual,
                          GiNaC::abs(f[r]) / size - Newton::_rounding(numeric(terms / size), eps_));
    }
    return residual;
  }

  // The row's points and outputs.
  void complete_row(const numeric& t) {
    row_.points.clear();
    const auto& points = model_.mechanism().points;
    for (std::size_t p = 0; p < points.size(); ++p) {
      const int b = 3 * points[p].body;
      const numeric c = GiNaC::cos(row_.q[b + 2]), s = GiNaC::sin(row_.q[b + 2]);
      row_.points.push_back(point_kinematics(&row_.q[b], &row_.qd[b], &row_.qdd[b], c, s,
                                             offsets_[p][0], offsets_[p][1]));
    }
    row_.outputs.clear();
    if (output_tape_ >= 0) {
      const Vector v = eval_.evaluate(output_tape_, row_.q, row_.qd, t);
      assemble_outputs(sym_.output_reads_velocity, nq_, v.data(), v.data() + num_outputs_,
                       row_.qdd.data(), numeric(0), row_.outputs);
      row_.velocity_outputs = sym_.output_reads_velocity;
    }
  }

  const CompiledModel& model_;
  const int digits_;
  HighPrecisionEvaluator eval_;
  const int nq_;
  const std::string& file_;
  const SymbolicModel& sym_;
  numeric eps_, tolerance_, stagnation_, residual_tolerance_, pivot_ratio_;
  std::vector<numeric> inv_scale_;  // per coordinate, as the runtime measures steps
  std::vector<std::array<numeric, 2>> offsets_;
  int num_outputs_ = 0, output_tape_ = -1;
  ReferenceRow row_;
  Lu lu_;
  double td_ = 0;  // the time as asked, for messages
};

}  // namespace

void run_reference_analysis_exact(const CompiledModel& model, const TimeGrid& grid, int digits,
                                  const std::function<void(const ReferenceRow&)>& sink) {
  if (digits < kMinReferenceDigits || digits > kMaxReferenceDigits)
    throw UsageError("reference digits must be between " + std::to_string(kMinReferenceDigits) +
                     " and " + std::to_string(kMaxReferenceDigits) + ", not " +
                     std::to_string(digits));
  require_driven(model);
  // Redundant constraints (nc > nq) need the double analysis' least squares.
  if (model.nc() != model.nq())
    throw UsageError("the reference analysis needs as many equations as coordinates (" +
                     std::to_string(model.nc()) + " equations, " + std::to_string(model.nq()) +
                     " coordinates); analyze without --reference-digits handles redundancy");
  const DigitsGuard guard(digits);
  ReferenceRun(model, digits).run(grid, sink);
}

void run_reference_analysis(const CompiledModel& model, const TimeGrid& grid, int digits,
                            const std::function<void(const StateRow&)>& sink) {
  run_reference_analysis_exact(model, grid, digits,
                               [&](const ReferenceRow& row) { sink(to_state_row(row)); });
}

}  // namespace kinegen::codegen
