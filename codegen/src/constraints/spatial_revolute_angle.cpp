// revolute_angle (spatial driver): the angle theta of body j about axis_i of a revolute or
// cylindrical joint (right-hand rule), from f_i to f_j, f_j being f_i carried into body j at
// the q0 pose (so theta = angle0 there): with F = f - angle0,
// sin(F) (f_i^T f_j) - cos(F) (g_i^T f_j) = 0, tracked on the branch theta = f.
#include "spatial_common.hpp"

namespace kinegen::codegen {

namespace {

// f_i . f_j and g_i . f_j (global), and F = f - angle0.
struct Measured {
  GiNaC::ex cosine, sine, angle;
};

Measured measured(const EquationContext& c) {
  using namespace spatial;
  const EquationContext jc = c.joint_context();
  const Constraint& joint = jc.constraint();
  const std::string type = joint.type_name();
  if (type != "revolute" && type != "cylindrical")
    c.fail("joint", "'" + joint.name + "' is a " + type +
                        " joint; revolute_angle drives a revolute or cylindrical joint");
  const V3 ai = unit_axis(jc, "axis_i"), aj = unit_axis(jc, "axis_j");
  const Normals n = normals(jc, ai);
  const Eigen::Matrix3d rj = aligned_rotation0(jc, numbers(jc, ai), numbers(jc, aj));
  const V3 fj = exact(carried(rj, jc.rotation0(joint.i) * numbers(jc, n.f)).normalized());
  const V3 f_j = global(jc, joint.j, fj);
  return {dot(global(jc, joint.i, n.f), f_j), dot(global(jc, joint.i, n.g), f_j),
          c.value() - c.scalar("angle0")};
}

std::vector<GiNaC::ex> revolute_angle_equations(const EquationContext& c) {
  const Measured m = measured(c);
  return {GiNaC::sin(m.angle) * m.cosine - GiNaC::cos(m.angle) * m.sine};
}

// The row also holds at theta = f + pi; the branch theta = f has cos(theta - f) > 0.
BranchConditions revolute_angle_branch(const EquationContext& c) {
  const Measured m = measured(c);
  return {{GiNaC::cos(m.angle) * m.cosine + GiNaC::sin(m.angle) * m.sine, "cos(theta - f)"}};
}

}  // namespace

extern const ConstraintKind kSpatialRevoluteAngle{
    .name = "revolute_angle",
    .joint = false,
    .driver = true,
    .keys = {{"joint", KeyKind::kJoint, true},
             {"angle0", KeyKind::kScalar, false},
             {"value", KeyKind::kValue, true}},
    .rows = 1,
    .equations = revolute_angle_equations,
    .reaction = false,
    .space = KindSpace::kSpatial,
};

extern const SpatialBranch kSpatialRevoluteAngleBranch{&kSpatialRevoluteAngle,
                                                       revolute_angle_branch};

}  // namespace kinegen::codegen
