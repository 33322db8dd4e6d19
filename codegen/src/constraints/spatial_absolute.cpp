// absolute_x, absolute_y, absolute_z (spatial): the global coordinate of point s of a body is
// `value` (a driver: f(t)). One file for the three: they differ only in the axis.
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

template <int kAxis>
std::vector<GiNaC::ex> absolute3_equations(const EquationContext& c) {
  const auto f = c.frame3(c.constraint().i);
  const auto s = EquationContext::rotate3(f.p, c.vector3("s"));
  return {f.r[kAxis] + s[kAxis] - c.value()};
}

ConstraintKind absolute3(const char* name, decltype(&absolute3_equations<0>) eq) {
  return {
      .name = name,
      .joint = true,
      .driver = true,
      .keys = {{"body", KeyKind::kBody, true},
               {"s", KeyKind::kOffset, false},
               {"value", KeyKind::kValue, true}},
      .rows = 1,
      .equations = eq,
      .reaction_i = "s",
      .space = KindSpace::kSpatial,
  };
}

}  // namespace

extern const ConstraintKind kSpatialAbsoluteX = absolute3("absolute_x", absolute3_equations<0>);
extern const ConstraintKind kSpatialAbsoluteY = absolute3("absolute_y", absolute3_equations<1>);
extern const ConstraintKind kSpatialAbsoluteZ = absolute3("absolute_z", absolute3_equations<2>);

}  // namespace kinegen::codegen
