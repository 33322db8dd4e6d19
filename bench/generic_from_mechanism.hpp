// Builds the generic solver's data description (numbers only) from kinegen's parsed and
// compiled mechanism: parameters substituted, local vectors evaluated, drivers reduced to
// f(t) = value + rate * t. The generic solver itself never sees an expression.
#pragma once

#include <optional>
#include <string>

#include "generic_solver.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"

namespace kinegen::generic {

// The description of `model`, or nullopt with `why` set when the generic joint library cannot
// express it (`expression` constraints, drivers not linear in t). With skip_free, the free
// items are left out: the joints and prescribed drivers of a dynamics model.
inline std::optional<MechanismData> from_compiled_model(const codegen::CompiledModel& model,
                                                        std::string& why,
                                                        bool skip_free = false) {
  const auto& mech = model.mechanism();
  const auto& symbols = model.symbols();
  const auto& values = model.symbolic().param_values;
  auto number = [&](const codegen::Expr& e, const std::string& item) {
    return codegen::to_double(codegen::substitute_params(
        symbols.parse(e, codegen::Scope::kGeometry, item), symbols, values));
  };
  auto vec = [&](const codegen::Vec2& v, const std::string& item) {
    return Eigen::Vector2d(number(v.x, item), number(v.y, item));
  };

  MechanismData data;
  data.bodies = static_cast<int>(mech.bodies.size());
  data.q0 = model.q0();
  data.length_scale = model.symbolic().length_scale;
  for (const codegen::Constraint* c : mech.constraints()) {
    if (skip_free && c->free) continue;
    JointRecord jr;
    jr.is_driver = c->is_driver;
    jr.i = c->i;
    jr.j = c->j;
    jr.formulas = find_joint_formulas(c->type_name());
    if (!jr.formulas) {
      why = c->item + ": `" + c->type_name() + "` constraints are not in the generic joint library";
      return std::nullopt;
    }
    // The library's local vectors by the format's key names (s of absolute_x/_y is its si).
    for (const auto& [key, v] : c->vectors) {
      if (key == "si" || key == "s") jr.si = vec(v, c->item);
      if (key == "sj") jr.sj = vec(v, c->item);
      if (key == "vi") jr.vi = vec(v, c->item);
    }
    if (c->is_driver) {
      const GiNaC::ex f = codegen::substitute_params(
          symbols.parse(c->value, codegen::Scope::kDriverTime, c->item), symbols, values);
      const GiNaC::ex rate = f.diff(symbols.t());
      if (!rate.diff(symbols.t()).is_zero()) {
        why = c->item + ": f(t) is not linear in t";
        return std::nullopt;
      }
      jr.value = codegen::to_double(f.subs(symbols.t() == 0));
      jr.rate = codegen::to_double(rate);
    } else if (!c->value.text.empty()) {
      jr.value = number(c->value, c->item);
    }
    data.joints.push_back(jr);
  }
  return data;
}

}  // namespace kinegen::generic
