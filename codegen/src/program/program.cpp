#include "kinegen/codegen/program/program.hpp"

#include <cstdlib>
#include <map>
#include <optional>
#include <stdexcept>

#include "kinegen/codegen/program/canonical_key.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

namespace {

class Lowerer {
 public:
  explicit Lowerer(const SymbolTable& symbols) : symbols_(symbols), keys_(symbols) {}

  int lower(const ex& e) {
    const auto it = memo_.find(e);
    if (it != memo_.end()) return it->second;
    const int id = build(e);
    memo_.emplace(e, id);
    return id;
  }

  Program finish(std::vector<int> outputs) {
    program_.outputs = std::move(outputs);
    compact();
    return std::move(program_);
  }

 private:
  int add(Node n) {
    program_.nodes.push_back(std::move(n));
    return static_cast<int>(program_.nodes.size()) - 1;
  }

  int constant(const ex& e) {
    Node n;
    n.kind = OpKind::kConst;
    n.exact = e;
    n.value = to_double(e);
    return add(std::move(n));
  }

  bool is_const(int id) const { return program_.nodes[id].kind == OpKind::kConst; }

  int build(const ex& e) {
    if (GiNaC::is_a<GiNaC::numeric>(e) || GiNaC::is_a<GiNaC::constant>(e)) return constant(e);
    if (GiNaC::is_a<GiNaC::symbol>(e)) {
      Node n;
      n.kind = OpKind::kInput;
      n.input = symbols_.classify(e);
      return add(std::move(n));
    }
    Node n;
    n.kind = OpKind::kAdd;
    if (GiNaC::is_a<GiNaC::add>(e)) {
      n.kind = OpKind::kAdd;
      // GiNaC orders operands by hashes that vary from run to run (they mix in addresses), so
      // operands are put in an order of our own: the same program, and the same rounding,
      // every time.
      for (const ex& operand : keys_.canonical_sum(e)) n.args.push_back(lower(operand));
    } else if (GiNaC::is_a<GiNaC::mul>(e)) {
      n.kind = OpKind::kMul;
      // GiNaC may hold c*(a - b)*x as -c*(b - a)*x, again by hash order: factors are taken
      // under CanonicalKey's sign convention, in its order, before any is lowered (node
      // numbers, and so the `_tK` names, follow the order of lowering, which must not be
      // GiNaC's).
      const CanonicalKey::Product p = keys_.canonical_product(e);
      // The coefficient goes first: it reads as `T(2)*x*y`, and both back ends multiply in
      // this order.
      if (p.coefficient != 1 || p.factors.size() < 2) n.args.push_back(lower(p.coefficient));
      for (const ex& f : p.factors) n.args.push_back(lower(f));
      if (n.args.size() == 1) return n.args[0];
    } else if (keys_.is_flipped_power(e)) {
      const CanonicalKey::Factor c = keys_.canonical_factor(e);
      const int node = lower(c.form);
      if (!c.negated) return node;
      n.kind = OpKind::kMul;
      n.args = {lower(ex(-1)), node};
    } else if (GiNaC::is_a<GiNaC::power>(e)) {
      return lower_power(e, std::move(n));
    } else if (is_motion_law(e, n.law, n.order)) {
      n.kind = OpKind::kMotionLaw;
      n.args = {lower(e.op(2))};
    } else if (is_table(e, n.table, n.order)) {
      n.kind = OpKind::kTable;
      n.args = {lower(e.op(2))};
    } else if (is_input(e, n.table, n.order)) {
      if (n.order > 2) throw std::logic_error("an input driver differentiated more than twice");
      n.kind = OpKind::kDriverInput;
    } else if (is_select(e)) {
      n.kind = OpKind::kSelect;
      n.args = {lower(e.op(0)), lower(e.op(1)), lower(e.op(2))};
    } else if (is_floor(e)) {
      n.kind = OpKind::kFloor;
      n.args = {lower(e.op(0))};
    } else if (GiNaC::is_a<GiNaC::function>(e)) {
      const std::string name = GiNaC::ex_to<GiNaC::function>(e).get_name();
      const MathFunction* f = find_math_function(name);
      if (!f || e.nops() != 1)
        throw std::logic_error("unsupported function in a derived expression: " + name);
      n.kind = f->op;
      n.args = {lower(e.op(0))};
    } else {
      throw std::logic_error("unsupported expression class: " +
                             std::string(GiNaC::ex_to<GiNaC::basic>(e).class_name()));
    }
    return fold_or_add(std::move(n), e);
  }

  // A power: an integer exponent, a square root (and its reciprocal) or pow.
  int lower_power(const ex& e, Node n) {
    const ex base = e.op(0), exponent = e.op(1);
    const int b = lower(base);
    if (GiNaC::is_a<GiNaC::numeric>(exponent)) {
      const GiNaC::numeric x = GiNaC::ex_to<GiNaC::numeric>(exponent);
      if (x.is_integer()) {
        n.kind = OpKind::kPowInt;
        n.args = {b};
        n.exponent = x.to_int();
      } else if (x == GiNaC::numeric(1, 2)) {
        n.kind = OpKind::kSqrt;
        n.args = {b};
      } else if (x.denom() == 2 && GiNaC::abs(x) <= kMaxUnrolledPower) {
        // x^(m + 1/2) = x^m sqrt(x), and x^-(m + 1/2) its reciprocal: a rounding or two more
        // than pow, several times faster, and the sqrt shared with the expressions' others.
        if (x.is_negative()) {
          n.kind = OpKind::kPowInt;
          n.args = {lower(GiNaC::power(base, -x))};
          n.exponent = -1;
        } else {
          n.kind = OpKind::kMul;
          n.args = {lower(GiNaC::power(base, x - GiNaC::numeric(1, 2))), lower(GiNaC::sqrt(base))};
        }
      } else {
        n.kind = OpKind::kPow;
        n.args = {b, lower(exponent)};
      }
    } else {
      n.kind = OpKind::kPow;
      n.args = {b, lower(exponent)};
    }
    return fold_or_add(std::move(n), e);
  }

  // A node whose arguments are all constants is itself a constant: fold it to one literal.
  int fold_or_add(Node n, const ex& e) {
    bool all_const = !n.args.empty();
    for (int a : n.args) all_const = all_const && is_const(a);
    if (all_const) return constant(e);
    return add(std::move(n));
  }

  // Counts uses and drops nodes nothing refers to (children of folded constants), keeping
  // dependency order.
  void compact() {
    auto& nodes = program_.nodes;
    for (auto& n : nodes) n.uses = 0;
    for (int o : program_.outputs)
      if (o != Program::kZero) ++nodes[o].uses;
    for (int k = static_cast<int>(nodes.size()) - 1; k >= 0; --k)
      if (nodes[k].uses > 0)
        for (int a : nodes[k].args) ++nodes[a].uses;
    std::vector<int> remap(nodes.size(), -1);
    std::vector<Node> kept;
    for (std::size_t k = 0; k < nodes.size(); ++k) {
      if (nodes[k].uses == 0) continue;
      remap[k] = static_cast<int>(kept.size());
      Node n = std::move(nodes[k]);
      for (int& a : n.args) a = remap[a];
      kept.push_back(std::move(n));
    }
    nodes = std::move(kept);
    for (int& o : program_.outputs)
      if (o != Program::kZero) o = remap[o];
    const auto computed = [](const Node& n) {
      return n.kind != OpKind::kConst && n.kind != OpKind::kInput;
    };
    for (auto& n : nodes) {
      if (computed(n) && n.uses > 1) n.named = true;
      if (n.kind == OpKind::kPowInt && std::abs(n.exponent) >= 2 &&
          std::abs(n.exponent) <= kMaxUnrolledPower && computed(nodes[n.args[0]]))
        nodes[n.args[0]].named = true;
    }
  }

  const SymbolTable& symbols_;
  CanonicalKey keys_;
  Program program_;
  std::map<ex, int, GiNaC::ex_is_less> memo_;
};

}  // namespace

bool Program::reads(InputKind kind) const {
  for (const auto& n : nodes)
    if (n.kind == OpKind::kInput && n.input.kind == kind) return true;
  return false;
}

int Program::operation_count() const {
  int count = 0;
  for (const auto& n : nodes) count += n.kind != OpKind::kConst && n.kind != OpKind::kInput;
  return count;
}

Program lower(const std::vector<ex>& outputs, const SymbolTable& symbols) {
  Lowerer lowerer(symbols);
  std::vector<int> ids;
  for (const auto& e : outputs) ids.push_back(e.is_zero() ? Program::kZero : lowerer.lower(e));
  return lowerer.finish(std::move(ids));
}

ModelPrograms lower_model(const SymbolicModel& model, const SymbolTable& symbols, int nq) {
  ModelPrograms p;
  p.nq = nq;
  p.nc = static_cast<int>(model.phi.size());
  std::vector<ex> jac;
  for (const auto& e : model.phi_q) {
    p.jac_rows.push_back(e.row);
    p.jac_cols.push_back(e.col);
    jac.push_back(e.value);
  }
  p.phi = lower(model.phi, symbols);
  p.phi_q = lower(jac, symbols);
  p.nu = lower(model.nu, symbols);
  p.gamma = lower(model.gamma, symbols);
  p.num_outputs = static_cast<int>(model.output_values.size());
  p.outputs = lower(model.output_values, symbols);
  p.output_rates = lower(output_rate_expressions(model), symbols);
  p.output_reads_velocity = model.output_reads_velocity;
  return p;
}

std::vector<ex> output_rate_expressions(const SymbolicModel& model) {
  std::vector<ex> all = model.output_rates;
  all.insert(all.end(), model.output_a0.begin(), model.output_a0.end());
  all.insert(all.end(), model.output_q.begin(), model.output_q.end());
  all.insert(all.end(), model.output_qd.begin(), model.output_qd.end());
  return all;
}

}  // namespace kinegen::codegen
