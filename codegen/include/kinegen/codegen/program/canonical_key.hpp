// A canonical order for GiNaC expressions. GiNaC orders the operands of sums and products by
// hashes that mix in addresses, so the order (and, for an even power of a sum, which sign the
// base is held with) varies from process to process. Whatever evaluates an expression in
// GiNaC's order rounds differently from run to run; CanonicalKey gives every subexpression a
// text independent of that order, and the forms a sum or product is evaluated in under it.
// The lowering (program.hpp) and the high-precision reference (analysis/reference.hpp) share it.
#pragma once

#include <ginac/ginac.h>

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

// The sign convention: a sum inside a product, or an integer power of a sum, is taken with a
// positive leading term (in an order that ignores signs), the sign moving to the product's
// coefficient. GiNaC would undo the rewrite, so callers evaluate the forms given here instead
// of the factors themselves. Keys are memoized, as nested sums are keyed at every level above.
class CanonicalKey {
 public:
  // `symbols` classifies every symbol met (q, qd, t, parameters); it must outlive this.
  explicit CanonicalKey(const SymbolTable& symbols) : symbols_(symbols) {}

  // A canonical text of `e`, independent of GiNaC's internal operand order.
  const std::string& key(const GiNaC::ex& e);

  // A product's factor's key under the sign convention, and whether it is taken negated.
  const std::pair<std::string, bool>& factor_key(const GiNaC::ex& factor);

  // Whether `e` is an integer power of a sum whose leading term is negative.
  bool is_flipped_power(const GiNaC::ex& e);

  // What a product's factor is evaluated as: `form` = factor, or -factor when `negated`.
  struct Factor {
    GiNaC::ex form;
    bool negated;
  };
  Factor canonical_factor(const GiNaC::ex& factor);

  // A product as its numeric coefficient (the negated factors' signs folded in) times the
  // forms of its other factors, in key order.
  struct Product {
    GiNaC::numeric coefficient;
    std::vector<GiNaC::ex> factors;
  };
  Product canonical_product(const GiNaC::ex& product);

  // A sum's operands in key order.
  std::vector<GiNaC::ex> canonical_sum(const GiNaC::ex& sum);

 private:
  bool leading_negative(const GiNaC::ex& sum);
  bool leading_negative_plain(const GiNaC::ex& sum);
  std::string unsigned_key(const GiNaC::ex& term);
  std::pair<std::string, bool> factor_key_plain(const GiNaC::ex& factor);
  std::string key_plain(const GiNaC::ex& e);

  const SymbolTable& symbols_;
  std::map<GiNaC::ex, std::string, GiNaC::ex_is_less> keys_;
  std::map<GiNaC::ex, std::pair<std::string, bool>, GiNaC::ex_is_less> factor_keys_;
  std::map<GiNaC::ex, bool, GiNaC::ex_is_less> leading_negative_;
};

}  // namespace kinegen::codegen
