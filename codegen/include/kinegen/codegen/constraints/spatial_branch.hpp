// The branch conditions of the spatial joint and driver types (docs/format.md, Spatial
// mechanisms): expressions in q and t that are > 0 on the branch a type holds (a hinge's axes
// pointing the same way, a revolute_angle's theta = f rather than f + pi), each with what a
// message calls it. A type with such conditions defines a SpatialBranch in its file, listed in
// registry.cpp; the analysis checks them after every position solve.
#pragma once

#include <ginac/ginac.h>

#include <string>
#include <utility>
#include <vector>

#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

using BranchConditions = std::vector<std::pair<GiNaC::ex, std::string>>;

struct SpatialBranch {
  const ConstraintKind* kind;
  BranchConditions (*conditions)(const EquationContext& context);
};

// The conditions of the constraint `context` describes (none for a type without a branch).
BranchConditions branch_conditions(const EquationContext& context);

}  // namespace kinegen::codegen
