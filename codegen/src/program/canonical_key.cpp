#include "kinegen/codegen/program/canonical_key.hpp"

#include <algorithm>
#include <sstream>

namespace kinegen::codegen {

using GiNaC::ex;

std::vector<ex> CanonicalKey::canonical_sum(const ex& sum) {
  std::vector<ex> operands(sum.begin(), sum.end());
  std::stable_sort(operands.begin(), operands.end(),
                   [&](const ex& a, const ex& b) { return key(a) < key(b); });
  return operands;
}

CanonicalKey::Product CanonicalKey::canonical_product(const ex& product) {
  // GiNaC may hold c*(a - b)*x as -c*(b - a)*x, again by hash order: the sign convention takes
  // both as the first.
  GiNaC::numeric sign = 1, coefficient = 1;
  std::vector<std::pair<std::string, ex>> factors;  // canonical key, factor
  for (const ex& factor : product) {
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
  Product p{coefficient * sign, {}};
  for (const auto& f : factors) p.factors.push_back(canonical_factor(f.second).form);
  return p;
}

CanonicalKey::Factor CanonicalKey::canonical_factor(const ex& factor) {
  const bool negated = factor_key(factor).second;
  if (GiNaC::is_a<GiNaC::add>(factor) && negated) return {-factor, true};
  if (is_flipped_power(factor)) {
    // The power of the flipped base, held: GiNaC gives an even power's base the sign its hash
    // order picks, so one process holds u^2 and another (-u)^2, and both must be the same
    // form (and so, where memoized, one shared node wherever it occurs).
    return {GiNaC::power(-factor.op(0), factor.op(1)).hold(), negated};
  }
  return {factor, false};
}

// Whether a sum's leading term, in an order that ignores signs, has a negative coefficient.
bool CanonicalKey::leading_negative(const ex& sum) {
  const auto it = leading_negative_.find(sum);
  if (it != leading_negative_.end()) return it->second;
  const bool negative = leading_negative_plain(sum);
  leading_negative_.emplace(sum, negative);
  return negative;
}

bool CanonicalKey::leading_negative_plain(const ex& sum) {
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

std::string CanonicalKey::unsigned_key(const ex& term) {
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

// Whether a product's factor is taken negated under the sign convention: a sum, or an integer
// power of a sum, whose leading term is negative.
bool CanonicalKey::is_flipped_power(const ex& e) {
  return GiNaC::is_a<GiNaC::power>(e) && GiNaC::is_a<GiNaC::add>(e.op(0)) &&
         e.op(1).info(GiNaC::info_flags::integer) && leading_negative(e.op(0));
}

const std::pair<std::string, bool>& CanonicalKey::factor_key(const ex& factor) {
  const auto it = factor_keys_.find(factor);
  if (it != factor_keys_.end()) return it->second;
  auto k = factor_key_plain(factor);
  return factor_keys_.emplace(factor, std::move(k)).first->second;
}

std::pair<std::string, bool> CanonicalKey::factor_key_plain(const ex& factor) {
  if (GiNaC::is_a<GiNaC::add>(factor) && leading_negative(factor)) return {key(-factor), true};
  if (is_flipped_power(factor)) {
    const GiNaC::numeric n = GiNaC::ex_to<GiNaC::numeric>(factor.op(1));
    return {"^(" + key(-factor.op(0)) + "," + key(n) + ")", n.is_odd()};
  }
  return {key(factor), false};
}

const std::string& CanonicalKey::key(const ex& e) {
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
    // Keyed as the product -1 * (-u)^n it equals: GiNaC holds that term of a sum as the power
    // (-u)^n in one process and as the product -u^n in another, and both must sort alike.
    const auto [pk, negated] = factor_key(e);
    k = negated ? "*(" + key(GiNaC::numeric(-1)) + "," + pk + ")" : pk;
  } else {
    k = key_plain(e);
  }
  return keys_.emplace(e, std::move(k)).first->second;
}

// The key of a non-product, operands in canonical order.
std::string CanonicalKey::key_plain(const ex& e) {
  std::vector<std::string> parts;
  for (const ex& operand : e) parts.push_back(key(operand));
  const bool commutative = GiNaC::is_a<GiNaC::add>(e);
  if (commutative) std::sort(parts.begin(), parts.end());
  std::string k;
  if (GiNaC::is_a<GiNaC::add>(e))
    k = "+";
  else if (GiNaC::is_a<GiNaC::mul>(e))
    k = "*";
  else if (GiNaC::is_a<GiNaC::power>(e))
    k = "^";
  else if (GiNaC::is_a<GiNaC::function>(e))
    k = GiNaC::ex_to<GiNaC::function>(e).get_name();
  else
    k = GiNaC::ex_to<GiNaC::basic>(e).class_name();
  k += "(";
  for (std::size_t i = 0; i < parts.size(); ++i) k += (i ? "," : "") + parts[i];
  k += ")";
  return k;
}

}  // namespace kinegen::codegen
