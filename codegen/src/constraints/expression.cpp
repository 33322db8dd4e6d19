// expression: equations written out, each string = 0; in the parameters and coordinates, and
// for a driver also t. Nothing is drawn for them: animate finds the points that move together.
#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

namespace {

std::vector<GiNaC::ex> expression_equations(const EquationContext& c) { return c.equations(); }

std::string expression_row_name(const Constraint&, int component) {
  return "equations[" + std::to_string(component) + "]";
}

}  // namespace

extern const ConstraintKind kExpression{
    .name = "expression",
    .joint = true,
    .driver = true,
    .keys = {{"equations", KeyKind::kEquations, true}},
    .rows = 0,  // one per equation
    .equations = expression_equations,
    .row_name = expression_row_name,
    .reaction = false,
    .space = KindSpace::kBoth,  // the coordinates by name, planar or spatial
};

}  // namespace kinegen::codegen
