#include "kinegen/codegen/analysis/reference.hpp"

#include <cln/cln.h>

#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>

#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/kinematics.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/program/canonical_key.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"
#include "kinegen/kernels/newton.hpp"
#include "kinegen/solver.hpp"

namespace kinegen::codegen {

using GiNaC::ex;
using GiNaC::numeric;

namespace {

enum class Op {
  kConst,
  kVar,
  kAdd,
  kMul,
  kPowInt,
  kPow,
  kFunction,
  kMotionLaw,
  kSelect,
  kFloor,
  kTable
};

numeric require_real(const numeric& v, const char* what) {
  if (!v.is_real())
    throw AnalysisError(std::string("a value is not real in the high-precision evaluation (") +
                        what + " outside its real domain)");
  return v;
}

}  // namespace

numeric exact_numeric(double value) {
  if (!std::isfinite(value)) throw std::domain_error("not a finite number");
  // numeric(double) holds a CLN double float; cln::rational gives its exact value.
  return numeric(cln::rational(cln::the<cln::cl_R>(numeric(value).to_cl_N())));
}

// One block's expressions as a list of operations in dependency order.
struct HighPrecisionEvaluator::Tape {
  struct Node {
    Op op = Op::kConst;
    std::vector<int> args;
    long exponent = 0;  // kPowInt
    numeric value;      // kConst
    int var = 0;        // kVar: q[0..nq), qd[nq..2nq), t at 2nq
    const MathFunction* function = nullptr;  // kFunction
    int law = 0, order = 0;                  // kMotionLaw; order also kTable
    int table = -1;                          // kTable
  };
  std::vector<Node> nodes;
  std::vector<int> outputs;  // -1: identically zero
  std::vector<numeric> values;
  std::vector<numeric> inputs;
};

namespace {

class TapeBuilder {
 public:
  TapeBuilder(const HighPrecisionEvaluator& owner, const CompiledModel& model)
      : owner_(owner), keys_(model.symbols()) {
    const SymbolTable& s = model.symbols();
    for (int k = 0; k < s.nq(); ++k) {
      vars_[s.q(k)] = k;
      vars_[s.qd(k)] = s.nq() + k;
    }
    vars_[s.t()] = 2 * s.nq();
  }

  template <class T>
  int compile(const ex& e, T& tape) {
    if (auto it = memo_.find(e); it != memo_.end()) return it->second;
    typename T::Node n;
    if (GiNaC::is_a<numeric>(e)) {
      n.value = owner_.to_float(require_real(GiNaC::ex_to<numeric>(e), "a constant"));
    } else if (GiNaC::is_a<GiNaC::constant>(e)) {
      n.value = owner_.to_float(GiNaC::ex_to<numeric>(GiNaC::evalf(e)));
    } else if (GiNaC::is_a<GiNaC::symbol>(e)) {
      const auto it = vars_.find(e);
      if (it == vars_.end()) throw std::logic_error("a symbol without a value: " + str(e));
      n.op = Op::kVar;
      n.var = it->second;
    } else if (GiNaC::is_a<GiNaC::add>(e)) {
      // GiNaC's operand order comes from hashes that mix in addresses, so it varies between
      // processes, and with it the rounding: sums and products are evaluated in the canonical
      // order and sign convention of the lowering (program/canonical_key.hpp) instead, so the
      // reference gives the same digits every run.
      n.op = Op::kAdd;
      for (const ex& operand : keys_.canonical_sum(e)) n.args.push_back(compile(operand, tape));
    } else if (GiNaC::is_a<GiNaC::mul>(e)) {
      n.op = Op::kMul;
      const CanonicalKey::Product p = keys_.canonical_product(e);
      if (p.coefficient != 1 || p.factors.size() < 2)
        n.args.push_back(compile(p.coefficient, tape));
      for (const ex& f : p.factors) n.args.push_back(compile(f, tape));
      if (n.args.size() == 1) return memo_[e] = n.args[0];
    } else if (keys_.is_flipped_power(e)) {
      // One process may hold u^2 and another (-u)^2: both become the same form.
      const CanonicalKey::Factor c = keys_.canonical_factor(e);
      const int node = compile(c.form, tape);
      if (!c.negated) return memo_[e] = node;
      n.op = Op::kMul;
      n.args = {compile(ex(-1), tape), node};
    } else if (GiNaC::is_a<GiNaC::power>(e)) {
      const ex expo = e.op(1);
      n.args.push_back(compile(e.op(0), tape));
      if (expo.info(GiNaC::info_flags::integer)) {
        n.op = Op::kPowInt;
        n.exponent = GiNaC::ex_to<numeric>(expo).to_long();
      } else if (expo.is_equal(GiNaC::ex(1) / 2)) {
        n.op = Op::kFunction;
        n.function = math_function(OpKind::kSqrt);
      } else {
        n.op = Op::kPow;
        n.args.push_back(compile(expo, tape));
      }
    } else if (is_motion_law(e, n.law, n.order)) {
      n.op = Op::kMotionLaw;
      n.args.push_back(compile(e.op(2), tape));
    } else if (is_table(e, n.table, n.order)) {
      n.op = Op::kTable;
      n.args.push_back(compile(e.op(2), tape));
    } else if (int driver = 0, order = 0; is_input(e, driver, order)) {
      n.value = 0;  // an input driver without a table: 0, as the evaluator takes it
    } else if (is_select(e) || is_floor(e)) {
      n.op = is_select(e) ? Op::kSelect : Op::kFloor;
      for (std::size_t k = 0; k < e.nops(); ++k) n.args.push_back(compile(e.op(k), tape));
    } else if (GiNaC::is_a<GiNaC::function>(e)) {
      n.function = find_math_function(GiNaC::ex_to<GiNaC::function>(e).get_name());
      if (!n.function || e.nops() != 1)
        throw std::logic_error("unsupported function in the reference: " + str(e));
      n.op = Op::kFunction;
      n.args.push_back(compile(e.op(0), tape));
    } else {
      throw std::logic_error("unsupported expression in the reference: " + str(e));
    }
    tape.nodes.push_back(std::move(n));
    const int id = static_cast<int>(tape.nodes.size()) - 1;
    memo_[e] = id;
    return id;
  }

 private:
  static std::string str(const ex& e) {
    std::ostringstream os;
    os << e;
    return os.str();
  }
  const HighPrecisionEvaluator& owner_;
  CanonicalKey keys_;
  std::map<ex, int, GiNaC::ex_is_less> vars_, memo_;
};

}  // namespace

HighPrecisionEvaluator::HighPrecisionEvaluator(const CompiledModel& model, int digits)
    : model_(&model), digits_(digits), nq_(model.nq()) {
  const auto& sym = model.symbolic();
  std::vector<ex> jac;
  for (const auto& e : sym.phi_q) jac.push_back(e.value);
  phi_ = build(sym.phi);
  phi_q_ = build(jac);
  nu_ = build(sym.nu);
  gamma_ = build(sym.gamma);
}

std::unique_ptr<HighPrecisionEvaluator::Tape> HighPrecisionEvaluator::build(
    const std::vector<ex>& outputs) const {
  const DigitsGuard guard(digits_);  // for evalf of pi
  auto tape = std::make_unique<Tape>();
  TapeBuilder builder(*this, *model_);
  for (const ex& e : outputs) {
    const ex v = substitute_params(e, model_->symbols(), model_->symbolic().param_values);
    tape->outputs.push_back(v.is_zero() ? -1 : builder.compile(v, *tape));
  }
  tape->values.resize(tape->nodes.size());
  return tape;
}

int HighPrecisionEvaluator::add_outputs(const std::vector<ex>& outputs) {
  extra_.push_back(build(outputs));
  return static_cast<int>(extra_.size()) - 1;
}

HighPrecisionEvaluator::~HighPrecisionEvaluator() = default;

numeric HighPrecisionEvaluator::to_float(const numeric& x) const {
  return numeric(cln::cl_float(cln::the<cln::cl_R>(x.to_cl_N()), cln::float_format(digits_)));
}

namespace {

using Vector = HighPrecisionEvaluator::Vector;

template <class Tape>
Vector run_tape(Tape& tape, const std::vector<numeric>& inputs) {
  auto& val = tape.values;
  for (std::size_t k = 0; k < tape.nodes.size(); ++k) {
    const auto& n = tape.nodes[k];
    const auto arg = [&](int a) -> const numeric& { return val[n.args[a]]; };
    switch (n.op) {
      case Op::kConst:
        val[k] = n.value;
        break;
      case Op::kVar:
        val[k] = inputs[n.var];
        break;
      case Op::kAdd: {
        numeric v = arg(0);
        for (std::size_t a = 1; a < n.args.size(); ++a) v = v + val[n.args[a]];
        val[k] = v;
        break;
      }
      case Op::kMul: {
        numeric v = arg(0);
        for (std::size_t a = 1; a < n.args.size(); ++a) v = v * val[n.args[a]];
        val[k] = v;
        break;
      }
      case Op::kPowInt: {
        // Binary powering: exact to working precision for the small exponents that occur.
        const long m = n.exponent < 0 ? -n.exponent : n.exponent;
        numeric base = arg(0), r = 1;
        for (long e = m; e > 0; e >>= 1) {
          if (e & 1) r = r * base;
          if (e > 1) base = base * base;
        }
        val[k] = n.exponent < 0 ? numeric(1) / r : r;
        break;
      }
      case Op::kPow:
        val[k] = require_real(arg(0).power(arg(1)), "a power");
        break;
      case Op::kFunction: {
        const numeric v = n.function->high_precision(arg(0));
        val[k] = n.function->partial ? require_real(v, n.function->name) : v;
        break;
      }
      case Op::kMotionLaw:
        val[k] = motion_law_high_precision(n.law, n.order, arg(0));
        break;
      case Op::kSelect:
        val[k] = arg(0).real().is_negative() ? arg(1) : arg(2);
        break;
      case Op::kFloor:
        val[k] = numeric(cln::floor1(cln::the<cln::cl_R>(arg(0).real().to_cl_N())));
        break;
      case Op::kTable:
        val[k] = spline_high_precision(registered_table(n.table), n.order, arg(0));
        break;
    }
  }
  Vector out;
  out.reserve(tape.outputs.size());
  for (int id : tape.outputs) out.push_back(id < 0 ? numeric(0) : val[id]);
  return out;
}

}  // namespace

Vector HighPrecisionEvaluator::run(Tape& tape, const Vector& q, const Vector* qd,
                                   const numeric& t) {
  auto& in = tape.inputs;
  in.assign(q.begin(), q.end());
  if (qd) {
    in.insert(in.end(), qd->begin(), qd->end());
  } else {
    in.resize(2 * nq_, numeric(0));
  }
  in.push_back(t);
  for (auto& v : in) v = to_float(v);
  return run_tape(tape, in);
}

Vector HighPrecisionEvaluator::phi(const Vector& q, const numeric& t) {
  return run(*phi_, q, nullptr, t);
}
Vector HighPrecisionEvaluator::phi_q_values(const Vector& q, const numeric& t) {
  return run(*phi_q_, q, nullptr, t);
}
Vector HighPrecisionEvaluator::nu(const Vector& q, const numeric& t) {
  return run(*nu_, q, nullptr, t);
}
Vector HighPrecisionEvaluator::gamma(const Vector& q, const Vector& qd, const numeric& t) {
  return run(*gamma_, q, &qd, t);
}
Vector HighPrecisionEvaluator::evaluate(int handle, const Vector& q, const Vector& qd,
                                        const numeric& t) {
  return run(*extra_[handle], q, &qd, t);
}

namespace {

// Dense LU with partial pivoting on numerics (n is small: 3 per body).
class Lu {
 public:
  // Returns false when a pivot is below `ratio` times the largest entry of the matrix.
  bool factor(std::vector<numeric> a, int n, const numeric& ratio) {
    a_ = std::move(a);
    n_ = n;
    perm_.resize(n);
    numeric largest = 0;
    for (const auto& v : a_) largest = std::max(largest, GiNaC::abs(v));
    if (largest.is_zero()) return false;
    for (int k = 0; k < n; ++k) perm_[k] = k;
    for (int k = 0; k < n; ++k) {
      int p = k;
      for (int r = k + 1; r < n; ++r)
        if (GiNaC::abs(at(r, k)) > GiNaC::abs(at(p, k))) p = r;
      if (GiNaC::abs(at(p, k)) <= ratio * largest) return false;
      if (p != k) {
        for (int c = 0; c < n; ++c) std::swap(at(p, c), at(k, c));
        std::swap(perm_[p], perm_[k]);
      }
      const numeric inv = numeric(1) / at(k, k);
      for (int r = k + 1; r < n; ++r) {
        if (at(r, k).is_zero()) continue;
        const numeric f = at(r, k) * inv;
        at(r, k) = f;
        for (int c = k + 1; c < n; ++c)
          if (!at(k, c).is_zero()) at(r, c) = at(r, c) - f * at(k, c);
      }
    }
    return true;
  }
  Vector solve(const Vector& b) const {
    Vector x(n_);
    for (int r = 0; r < n_; ++r) {
      numeric s = b[perm_[r]];
      for (int c = 0; c < r; ++c) s = s - at(r, c) * x[c];
      x[r] = s;
    }
    for (int r = n_ - 1; r >= 0; --r) {
      numeric s = x[r];
      for (int c = r + 1; c < n_; ++c) s = s - at(r, c) * x[c];
      x[r] = s / at(r, r);
    }
    return x;
  }

 private:
  numeric& at(int r, int c) { return a_[r * n_ + c]; }
  const numeric& at(int r, int c) const { return a_[r * n_ + c]; }
  std::vector<numeric> a_;
  std::vector<int> perm_;
  int n_ = 0;
};

}  // namespace

struct ReferenceForces::Data {
  ForceData<numeric> numbers;
  numeric pivot_ratio;
};

ReferenceForces::ReferenceForces(const CompiledModel& model, const ForceModel& forces,
                                 int digits)
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

namespace {

}  // namespace

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
  for (const auto& o : row.outputs)
    s.outputs.push_back({o[0].to_double(), o[1].to_double(), o[2].to_double()});
  return s;
}

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
  HighPrecisionEvaluator eval(model, digits);
  const int nq = model.nq();
  const std::string& file = model.mechanism().source;
  const auto& sym = model.symbolic();
  const numeric ten = 10;
  // The Newton policy of the runtime (kernels/newton.hpp) with eps = 10^-digits. Newton
  // converges quadratically, so a step of 10^-(digits-5) (plus the rounding allowance) leaves
  // an error far below the working precision; near it, rounding noise of cond(Phi_q)
  // 10^-digits could keep the step from falling further, so a step that stops decreasing
  // below 10^-(digits/2) ends it (_stalled). The residual is then rechecked against
  // 10^-(digits/2), as the double paths check 2^-(53/2). Phi_q's singularity is judged by the
  // LU's pivots (no condition estimate here, so no linear-convergence rule).
  using Newton = kernels::NewtonKernel;
  const numeric eps = ten.power(-digits);
  const numeric tolerance = ten.power(-(digits - 5));
  const numeric stagnation = ten.power(-(digits / 2));
  const numeric residual_tolerance = stagnation;
  const numeric pivot_ratio = ten.power(-(digits - 3));
  std::vector<numeric> inv_scale;  // per coordinate, as the runtime measures steps
  for (double scale : sym.coordinate_scales)
    inv_scale.push_back(eval.to_float(numeric(1) / exact_numeric(scale)));
  constexpr int kMaxIterations = 60;

  // Point offsets, exact parameters substituted.
  std::vector<std::array<numeric, 2>> offsets;
  for (const auto& [x, y] : sym.point_s) {
    const auto value = [&](const ex& e) {
      return eval.to_float(GiNaC::ex_to<numeric>(
          GiNaC::evalf(substitute_params(e, model.symbols(), sym.param_values))));
    };
    offsets.push_back({value(x), value(y)});
  }

  // Outputs: values, then rates, a0 and O_q (output_rate_expressions), in one tape.
  const int num_outputs = static_cast<int>(sym.output_values.size());
  int output_tape = -1;
  if (num_outputs > 0) {
    std::vector<ex> all = sym.output_values;
    for (const ex& e : output_rate_expressions(sym)) all.push_back(e);
    output_tape = eval.add_outputs(all);
  }

  const auto jacobian = [&](const Vector& q, const numeric& t) {
    std::vector<numeric> a(static_cast<std::size_t>(nq) * nq, numeric(0));
    const Vector values = eval.phi_q_values(q, t);
    for (std::size_t k = 0; k < values.size(); ++k)
      a[sym.phi_q[k].row * nq + sym.phi_q[k].col] = values[k];
    return a;
  };

  ReferenceRow row;
  const Eigen::VectorXd q0 = model.q0();
  for (int k = 0; k < nq; ++k) row.q.push_back(eval.to_float(exact_numeric(q0[k])));
  row.qd.assign(nq, numeric(0));
  row.qdd.assign(nq, numeric(0));
  Lu lu;
  for (int step = 0; step <= grid.steps; ++step) {
    const double td = grid.at(step);
    const numeric t = eval.to_float(exact_numeric(td));
    const auto fail = [&](const std::string& stage, const std::string& why) {
      throw AnalysisError(file + ": reference " + stage + " analysis (" + std::to_string(digits) +
                          " digits) failed at " + format_time(td) + ": " + why);
    };
    try {
      if (step > 0) {
        const numeric h = t - row.t;
        const numeric half_h2 = h * h / 2;
        for (int k = 0; k < nq; ++k) row.q[k] = row.q[k] + h * row.qd[k] + half_h2 * row.qdd[k];
      }
      row.t = t;
      // Position: Newton.
      numeric last_step = 0;  // 0: no step yet
      bool converged = false;
      int it = 1;
      for (; it <= kMaxIterations && !converged; ++it) {
        const Vector f = eval.phi(row.q, t);
        if (!lu.factor(jacobian(row.q, t), nq, pivot_ratio))
          fail("position", "the constraint Jacobian Phi_q is singular");
        const Vector dq = lu.solve(f);
        numeric size = 0;
        bool small = true;
        for (int k = 0; k < nq; ++k) {
          row.q[k] = row.q[k] - dq[k];
          const numeric d = GiNaC::abs(dq[k] * inv_scale[k]);
          size = std::max(size, d);
          small = small &&
                  Newton::_step_converged(d, GiNaC::abs(row.q[k] * inv_scale[k]), tolerance, eps);
        }
        converged = small || Newton::_stalled(size, last_step, stagnation);
        last_step = size;
      }
      row.newton_iterations = it - 1;
      // The residual recheck, on the Jacobian the velocity and acceleration then share (rows
      // scaled as on the double paths: by their largest |entry| times the column's scale).
      const std::vector<numeric> a = jacobian(row.q, t);
      numeric residual = 0;
      if (converged) {
        const Vector f = eval.phi(row.q, t);
        for (int r = 0; r < nq; ++r) {
          numeric size = 0, terms = 0;
          for (int k = 0; k < nq; ++k) {
            const numeric v = GiNaC::abs(a[r * nq + k]);
            if (v.is_zero()) continue;
            size = std::max(size, v / inv_scale[k]);
            terms = terms + v * GiNaC::abs(row.q[k]);
          }
          if (size.is_zero()) size = 1;
          residual = std::max(
              residual, GiNaC::abs(f[r]) / size - Newton::_rounding(numeric(terms / size), eps));
        }
      }
      const int status = Newton::_newton_status(false, converged, residual <= residual_tolerance,
                                                false, residual, numeric(1), numeric(0));
      if (status == static_cast<int>(Status::kMaxIterations))
        fail("position", "Newton iteration did not converge in " + std::to_string(kMaxIterations) +
                             " iterations; the mechanism may not assemble here");
      if (status != 0) fail("position", kinegen::to_string(static_cast<Status>(status)));
      // Velocity and acceleration share one factorization at the solved position.
      if (!lu.factor(a, nq, pivot_ratio))
        fail("velocity", "the constraint Jacobian Phi_q is singular");
      row.qd = lu.solve(eval.nu(row.q, t));
      row.qdd = lu.solve(eval.gamma(row.q, row.qd, t));
    } catch (const AnalysisError& e) {
      const std::string what = e.what();
      if (what.rfind(file + ": ", 0) == 0) throw;
      fail("position", what);
    }
    row.points.clear();
    const auto& points = model.mechanism().points;
    for (std::size_t p = 0; p < points.size(); ++p) {
      const int b = 3 * points[p].body;
      const numeric c = GiNaC::cos(row.q[b + 2]), s = GiNaC::sin(row.q[b + 2]);
      row.points.push_back(
          point_kinematics(&row.q[b], &row.qd[b], &row.qdd[b], c, s, offsets[p][0], offsets[p][1]));
    }
    row.outputs.clear();
    if (output_tape >= 0) {
      const Vector v = eval.evaluate(output_tape, row.q, row.qd, t);
      for (int o = 0; o < num_outputs; ++o) {
        numeric a = v[2 * num_outputs + o];
        for (int k = 0; k < nq; ++k) a = a + v[3 * num_outputs + o * nq + k] * row.qdd[k];
        row.outputs.push_back({v[o], v[num_outputs + o], a});
      }
    }
    sink(row);
  }
}

void run_reference_analysis(const CompiledModel& model, const TimeGrid& grid, int digits,
                            const std::function<void(const StateRow&)>& sink) {
  run_reference_analysis_exact(model, grid, digits,
                               [&](const ReferenceRow& row) { sink(to_state_row(row)); });
}

}  // namespace kinegen::codegen
