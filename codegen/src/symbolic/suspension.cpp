// The numbers of a `suspension:` block (docs/format.md, Suspension analysis) that only the
// parameters' values decide: a positive tire radius, a spin axis that is not zero and the
// design position's time. Its outputs are parsed as every output is (derive.cpp).
#include <cmath>
#include <string>

#include "kinegen/codegen/base/format.hpp"
#include "symbolic_detail.hpp"

namespace kinegen::codegen::symbolic_detail {

double check_suspension(const Mechanism& m, const SymbolTable& s,
                        const std::vector<GiNaC::numeric>& values) {
  const Suspension& susp = *m.suspension;
  const auto number = [&](const Expr& e, const std::string& item) {
    return to_double(substitute_params(geometry_value(m, s, values, e, item), s, values));
  };
  const double radius = number(susp.tire_radius, "suspension.tire_radius");
  if (!(radius > 0))
    throw InputError(m.source, "suspension.tire_radius", susp.tire_radius.loc,
                     "the tire radius must be positive, not " + format_number(radius));
  for (const Point& v : m.vectors) {
    if (v.name != susp.spin_axis) continue;
    const std::string item = "vector '" + v.name + "' v";
    const double x = number(v.s.x, item), y = number(v.s.y, item), z = number(v.s.z, item);
    if (!(std::sqrt(x * x + y * y + z * z) >= 1e-12))
      throw InputError(m.source, "vector '" + v.name + "'", v.loc,
                       "the suspension's spin axis must not be a zero vector");
  }
  return number(susp.design_t, "suspension.design_t");
}

}  // namespace kinegen::codegen::symbolic_detail
