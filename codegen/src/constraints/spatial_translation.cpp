// translation (spatial driver): the travel of sj from si along the axis of a translational or
// cylindrical joint, a_i^T d_ij - f = 0 with a_i = A_i axis_i normalized; 0 where the points
// coincide.
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> translation_equations(const EquationContext& c) {
  using namespace spatial;
  const EquationContext jc = c.joint_context();
  const Constraint& joint = jc.constraint();
  const std::string type = joint.type_name();
  if (type != "translational" && type != "cylindrical")
    c.fail("joint", "'" + joint.name + "' is a " + type +
                        " joint; translation drives a translational or cylindrical joint");
  return {dot(global(jc, joint.i, unit_axis(jc, "axis_i")), jc.d_ij3()) - c.value()};
}

}  // namespace

extern const ConstraintKind kSpatialTranslation{
    .name = "translation",
    .joint = false,
    .driver = true,
    .keys = {{"joint", KeyKind::kJoint, true}, {"value", KeyKind::kValue, true}},
    .rows = 1,
    .equations = translation_equations,
    .reaction = false,
    .space = KindSpace::kSpatial,
};

}  // namespace kinegen::codegen
