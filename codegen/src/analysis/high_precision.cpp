// HighPrecisionEvaluator (reference.hpp): a model's expressions as tapes in CLN arithmetic at
// D digits, in the canonical operand order of the double evaluator (canonical_key.hpp).
#include <cln/cln.h>

#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>

#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/program/canonical_key.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"

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
    long exponent = 0;                       // kPowInt
    numeric value;                           // kConst
    int var = 0;                             // kVar: q[0..nq), qd[nq..2nq), t at 2nq
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

}  // namespace kinegen::codegen
