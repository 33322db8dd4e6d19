#include "kinegen/codegen/program/program.hpp"

#include <algorithm>
#include <cstdlib>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "kinegen/codegen/symbolic/functions.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

namespace {

class Lowerer {
 public:
  explicit Lowerer(const SymbolTable& symbols) : symbols_(symbols) {}

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
      std::vector<ex> operands(e.begin(), e.end());
      std::stable_sort(operands.begin(), operands.end(),
                       [&](const ex& a, const ex& b) { return key(a) < key(b); });
      for (const ex& operand : operands) n.args.push_back(lower(operand));
    } else if (GiNaC::is_a<GiNaC::mul>(e)) {
      n.kind = OpKind::kMul;
      // GiNaC may hold c*(a - b)*x as -c*(b - a)*x, again by hash order. Every sum inside a
      // product (or an integer power in it) is taken with a positive leading term, the sign
      // moving to the coefficient; this is done on our nodes, as GiNaC would undo it.
      GiNaC::numeric sign = 1, coefficient = 1;
      // Factors are sorted by key before any is lowered: node numbers (and so the `_tK`
      // names) follow the order of lowering, which must not be GiNaC's.
      std::vector<std::pair<std::string, ex>> factors;  // canonical key, factor
      for (const ex& factor : e) {
        if (GiNaC::is_a<GiNaC::numeric>(factor)) {
          coefficient *= GiNaC::ex_to<GiNaC::numeric>(factor);
          continue;
        }
        const auto& [k, negated] = factor_key(factor);
        if (negated) sign = -sign;
        factors.emplace_back(k, factor);
      }
      std::stable_sort(factors.begin(), factors.end(),
                       [](const auto& a, const auto& b) { return a.first < b.first; });
      coefficient *= sign;
      // The coefficient goes first: it reads as `T(2)*x*y`, and both back ends multiply in
      // this order.
      if (coefficient != 1 || factors.size() < 2) n.args.push_back(lower(coefficient));
      for (const auto& f : factors) n.args.push_back(canonical_factor(f.second).node);
      if (n.args.size() == 1) return n.args[0];
    } else if (is_flipped_power(e)) {
      const CanonicalFactor c = canonical_factor(e);
      if (!c.negated) return c.node;
      n.kind = OpKind::kMul;
      n.args = {lower(ex(-1)), c.node};
    } else if (GiNaC::is_a<GiNaC::power>(e)) {
      const ex base = e.op(0), exponent = e.op(1);
      const int b = lower(base);
      if (GiNaC::is_a<GiNaC::numeric>(exponent)) {
        const GiNaC::numeric x = GiNaC::ex_to<GiNaC::numeric>(exponent);
        if (x.is_integer()) {
          n.kind = OpKind::kPowInt;
          n.args = {b};
          n.exponent = x.to_int();
        } else if (x == GiNaC::numeric(1, 2) || x == GiNaC::numeric(-1, 2)) {
          // x^(-1/2) = 1 / sqrt(x): a sqrt and a reciprocal, both exact to rounding.
          n.kind = OpKind::kSqrt;
          n.args = {b};
          if (x.is_negative()) {
            Node inv;
            inv.kind = OpKind::kPowInt;
            inv.args = {fold_or_add(std::move(n), GiNaC::sqrt(base))};
            inv.exponent = -1;
            return fold_or_add(std::move(inv), e);
          }
        } else {
          n.kind = OpKind::kPow;
          n.args = {b, lower(exponent)};
        }
      } else {
        n.kind = OpKind::kPow;
        n.args = {b, lower(exponent)};
      }
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

  // Whether a sum's leading term, in an order that ignores signs, has a negative coefficient.
  bool leading_negative(const ex& sum) {
    const auto it = leading_negative_.find(sum);
    if (it != leading_negative_.end()) return it->second;
    const bool negative = leading_negative_plain(sum);
    leading_negative_.emplace(sum, negative);
    return negative;
  }

  bool leading_negative_plain(const ex& sum) {
    ex lead;  // by value: GiNaC's iterators hand out temporaries
    std::string lead_key;
    bool first = true;
    for (const ex& term : sum) {
      std::string k = unsigned_key(term);
      if (first || k < lead_key) {
        lead = term;
        lead_key = std::move(k);
        first = false;
      }
    }
    if (first) return false;
    if (GiNaC::is_a<GiNaC::numeric>(lead)) return GiNaC::ex_to<GiNaC::numeric>(lead).is_negative();
    // The sign the term has under the convention: its coefficient, flipped once for every
    // factor that is itself taken negated.
    bool negative = false;
    if (GiNaC::is_a<GiNaC::mul>(lead)) {
      for (const ex& factor : lead) {
        if (GiNaC::is_a<GiNaC::numeric>(factor))
          negative ^= GiNaC::ex_to<GiNaC::numeric>(factor).is_negative();
        else
          negative ^= factor_key(factor).second;
      }
    } else {
      negative = factor_key(lead).second;
    }
    return negative;
  }

  std::string unsigned_key(const ex& term) {
    if (GiNaC::is_a<GiNaC::numeric>(term)) return key(GiNaC::abs(GiNaC::ex_to<GiNaC::numeric>(term)));
    // x and -x must get the same key, so a lone factor is keyed like a product too.
    if (!GiNaC::is_a<GiNaC::mul>(term)) return "*(" + factor_key(term).first + ",)";
    std::vector<std::string> parts;
    for (const ex& factor : term)
      if (!GiNaC::is_a<GiNaC::numeric>(factor)) parts.push_back(factor_key(factor).first);
    std::sort(parts.begin(), parts.end());
    std::string k = "*(";
    for (const auto& part : parts) k += part + ",";
    return k + ")";
  }

  struct CanonicalFactor {
    std::string key;
    int node;
    bool negated;
  };

  // Whether a product's factor is taken negated under the sign convention: a sum, or an
  // integer power of a sum, whose leading term is negative. Also its canonical key.
  bool is_flipped_power(const ex& e) {
    return GiNaC::is_a<GiNaC::power>(e) && GiNaC::is_a<GiNaC::add>(e.op(0)) &&
           e.op(1).info(GiNaC::info_flags::integer) && leading_negative(e.op(0));
  }

  // Memoized like key(): a nested sum would otherwise be keyed again at every level above it.
  const std::pair<std::string, bool>& factor_key(const ex& factor) {
    const auto it = factor_keys_.find(factor);
    if (it != factor_keys_.end()) return it->second;
    auto k = factor_key_plain(factor);
    return factor_keys_.emplace(factor, std::move(k)).first->second;
  }

  std::pair<std::string, bool> factor_key_plain(const ex& factor) {
    if (GiNaC::is_a<GiNaC::add>(factor) && leading_negative(factor)) return {key(-factor), true};
    if (is_flipped_power(factor)) {
      const GiNaC::numeric n = GiNaC::ex_to<GiNaC::numeric>(factor.op(1));
      return {"^(" + key(-factor.op(0)) + "," + key(n) + ")", n.is_odd()};
    }
    return {key(factor), false};
  }

  // A product's factor lowered under the sign convention (GiNaC would undo the rewrite, so it
  // is done on our nodes).
  CanonicalFactor canonical_factor(const ex& factor) {
    auto [k, negated] = factor_key(factor);
    if (GiNaC::is_a<GiNaC::add>(factor) && negated) return {k, lower(-factor), true};
    if (is_flipped_power(factor)) {
      // The held power of the flipped base, through the memo: GiNaC gives an even power's base
      // the sign its hash order picks, so one process holds u^2 and another (-u)^2, and each
      // must be one shared node wherever it occurs (a fresh node per occurrence left the
      // sharing, and so the header, to the hash order).
      const ex base = -factor.op(0);
      return {k, lower(GiNaC::power(base, factor.op(1)).hold()), negated};
    }
    return {k, lower(factor), false};
  }

  // A canonical text of `e`, independent of GiNaC's internal operand order.
  const std::string& key(const ex& e) {
    const auto it = keys_.find(e);
    if (it != keys_.end()) return it->second;
    std::string k;
    if (GiNaC::is_a<GiNaC::symbol>(e)) {
      const Input in = symbols_.classify(e);
      static const char kPrefix[] = {'q', 'v', 't', 'p'};
      k = kPrefix[static_cast<int>(in.kind)] + std::to_string(in.index);
    } else if (GiNaC::is_a<GiNaC::numeric>(e) || GiNaC::is_a<GiNaC::constant>(e)) {
      std::ostringstream os;
      os << e;
      k = "#" + os.str();
    } else if (GiNaC::is_a<GiNaC::mul>(e)) {
      GiNaC::numeric coefficient = 1;
      std::vector<std::string> parts;
      for (const ex& factor : e) {
        if (GiNaC::is_a<GiNaC::numeric>(factor)) {
          coefficient *= GiNaC::ex_to<GiNaC::numeric>(factor);
          continue;
        }
        auto [fk, negated] = factor_key(factor);
        if (negated) coefficient = -coefficient;
        parts.push_back(std::move(fk));
      }
      std::sort(parts.begin(), parts.end());
      k = "*(" + key(coefficient);
      for (const auto& part : parts) k += "," + part;
      k += ")";
    } else if (is_flipped_power(e)) {
      const auto [pk, negated] = factor_key(e);
      k = negated ? "-" + pk : pk;
    } else {
      k = key_plain(e);
    }
    return keys_.emplace(e, std::move(k)).first->second;
  }

  // The key of a non-product, operands in canonical order.
  std::string key_plain(const ex& e) {
    std::string k;
    {
      std::vector<std::string> parts;
      for (const ex& operand : e) parts.push_back(key(operand));
      const bool commutative = GiNaC::is_a<GiNaC::add>(e);
      if (commutative) std::sort(parts.begin(), parts.end());
      if (GiNaC::is_a<GiNaC::add>(e)) k = "+";
      else if (GiNaC::is_a<GiNaC::mul>(e)) k = "*";
      else if (GiNaC::is_a<GiNaC::power>(e)) k = "^";
      else if (GiNaC::is_a<GiNaC::function>(e)) k = GiNaC::ex_to<GiNaC::function>(e).get_name();
      else k = GiNaC::ex_to<GiNaC::basic>(e).class_name();
      k += "(";
      for (std::size_t i = 0; i < parts.size(); ++i) k += (i ? "," : "") + parts[i];
      k += ")";
    }
    return k;
  }

  const SymbolTable& symbols_;
  Program program_;
  std::map<ex, std::string, GiNaC::ex_is_less> keys_;
  std::map<ex, std::pair<std::string, bool>, GiNaC::ex_is_less> factor_keys_;
  std::map<ex, bool, GiNaC::ex_is_less> leading_negative_;
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
  return p;
}

std::vector<ex> output_rate_expressions(const SymbolicModel& model) {
  std::vector<ex> all = model.output_rates;
  all.insert(all.end(), model.output_a0.begin(), model.output_a0.end());
  all.insert(all.end(), model.output_q.begin(), model.output_q.end());
  return all;
}

}  // namespace kinegen::codegen
