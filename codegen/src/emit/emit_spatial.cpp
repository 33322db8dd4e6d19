// What a spatial file's header adds (docs/format.md, Spatial mechanisms): the branch conditions
// every position solve checks (_branches_hold, called by solve_position and solve_step), and
// each driver's row at a value v of its own, for the first solve's continuation from the q0
// pose (kinegen/driver_continuation.hpp): every driver moves from its value at the start pose
// to f(t), as `kinegen analyze` moves it.
#include <string>
#include <vector>

#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/constraints/spatial_branch.hpp"
#include "printer.hpp"
#include "sections.hpp"

namespace kinegen::codegen::emit_detail {

using GiNaC::ex;

namespace {

// The parameters' values where the header folds them, else e unchanged.
ex spatial_folded(const CompiledModel& compiled, const ex& e) {
  return compiled.build_options().fold_params
             ? substitute_params(e, compiled.symbols(), compiled.symbolic().param_values)
             : e;
}

void emit_spatial_branches(std::ostringstream& os, const CompiledModel& compiled, int max_ops) {
  const Mechanism& m = compiled.mechanism();
  const SymbolTable& s = compiled.symbols();
  const auto& values = compiled.symbolic().param_values;
  std::vector<ex> conditions;
  os << "\n  // Branch conditions, each > 0 on the assembly the motion continues (docs/format.md,\n"
     << "  // Spatial mechanisms); solve_position and solve_step fail with status 6 otherwise:\n";
  for (const Constraint* c : m.constraints())
    for (auto& [value, what] : branch_conditions(EquationContext(*c, m, s, values))) {
      // The item is built from validated names, `what` is the registry's text.
      os << "  //   " << conditions.size() << ": " << c->item << ", " << what << "\n";
      conditions.push_back(spatial_folded(compiled, value));
    }
  os << "  static constexpr int num_branches = " << conditions.size() << ";\n";
  if (!conditions.empty())
    emit_function(os, "_branch_values", "num_branches", lower(conditions, s), s, false, max_ops);
  os << "  // Whether every branch condition holds at q (NaN fails).\n"
     << "  template <class T>\n"
     << "  static bool _branches_hold([[maybe_unused]] const T* q, [[maybe_unused]] T t,\n"
     << "                             [[maybe_unused]] const Params& p) noexcept {\n";
  if (conditions.empty()) {
    os << "    return true;\n  }\n";
    return;
  }
  os << "    T v[num_branches];\n"
     << "    _branch_values(q, t, p, v);\n"
     << "    for (int k = 0; k < num_branches; ++k)\n"
     << "      if (!(_re(v[k]) > 0)) return false;\n"
     << "    return true;\n  }\n";
}

// The drivers' rows by value: driver k's row with its f replaced by v, its value at a pose and
// f(t), and the largest change of v per continuation step.
void emit_spatial_continuation(std::ostringstream& os, const CompiledModel& compiled, int max_ops) {
  const Mechanism& m = compiled.mechanism();
  const SymbolTable& s = compiled.symbols();
  const SymbolicModel& model = compiled.symbolic();
  const auto& values = model.param_values;
  std::vector<std::string> rows, steps, first, count;
  std::vector<ex> start_and_target, start_values, targets;
  std::vector<std::vector<ex>> row_programs;
  for (std::size_t r = 0; r < model.rows.size(); ++r) {
    const Constraint& c = *model.rows[r].constraint;
    if (!c.is_driver || c.kind->rows == 0) continue;  // expression drivers hold at t
    Constraint by_value = c;
    by_value.value = Expr{"t", c.loc};
    by_value.law = DriverLaw{};
    const ex h =
        spatial_folded(compiled, c.kind->equations(EquationContext(by_value, m, s, values))[0]);
    std::vector<ex> outs{h};
    int at = -1, n = 0;
    for (std::size_t e = 0; e < model.phi_q.size(); ++e) {
      if (model.phi_q[e].row != static_cast<int>(r)) continue;
      if (at < 0) at = static_cast<int>(e);
      ++n;
      outs.push_back(h.diff(GiNaC::ex_to<GiNaC::symbol>(s.q(model.phi_q[e].col))));
    }
    // Its value at a pose: h(q, v) = g(q) - v, or |d|^2 - v^2 for a distance; angle0 for a
    // revolute_angle (by its definition, theta = angle0 at the q0 pose).
    const std::string type = c.type_name();
    ex start = h.subs(s.t() == 0);
    if (type == "revolute_angle")
      start = spatial_folded(compiled, EquationContext(c, m, s, values).scalar("angle0"));
    else if (c.kind->squared_distance)
      start = GiNaC::sqrt(start);
    start_values.push_back(start);
    targets.push_back(spatial_folded(compiled, EquationContext(c, m, s, values).value()));
    rows.push_back(std::to_string(r));
    steps.push_back(
        format_double(type == "revolute_angle" || type == "dp1" ? 0.25 : 0.1 * model.length_scale));
    first.push_back(std::to_string(at < 0 ? 0 : at));
    count.push_back(std::to_string(n));
    row_programs.push_back(std::move(outs));
  }
  const int k = static_cast<int>(rows.size());
  os << "\n  // The first solve's continuation from the q0 pose "
        "(kinegen/driver_continuation.hpp):\n"
     << "  // each driver's row of Phi, its largest change per step (0.25 rad or 0.1 of the\n"
     << "  // length scale) and where its Phi_q entries are (first, count in jac order).\n"
     << "  static constexpr int num_continued = " << k << ";\n";
  if (k == 0) return;
  os << "  static constexpr std::array<int, num_continued> continued_rows = {" << join(rows)
     << "};\n"
     << "  static constexpr std::array<double, num_continued> continued_steps = {" << join(steps)
     << "};\n"
     << "  static constexpr std::array<int, num_continued> continued_first = {" << join(first)
     << "};\n"
     << "  static constexpr std::array<int, num_continued> continued_count = {" << join(count)
     << "};\n"
     << "  // out[k]: driver k's value at the pose q; out[num_continued + k]: its value f(t).\n";
  start_and_target = start_values;
  start_and_target.insert(start_and_target.end(), targets.begin(), targets.end());
  emit_function(os, "_continued_values", "2 * num_continued", lower(start_and_target, s), s, false,
                max_ops);
  for (int d = 0; d < k; ++d) {
    os << "  // Driver " << d
       << "'s row with the value t in place of f: the residual, then its "
          "Phi_q entries.\n";
    const std::string name = "_continued_row" + std::to_string(d);
    const std::string size = std::to_string(row_programs[d].size());
    emit_function(os, name.c_str(), size.c_str(), lower(row_programs[d], s), s, false, max_ops);
  }
  os << "  // Driver k's row at the value v (out: 1 + continued_count[k] values).\n"
     << "  template <class T>\n"
     << "  static void _continued_row(int k, const T* q, T v, const Params& p, T* out) noexcept {\n"
     << "    switch (k) {\n";
  for (int d = 0; d < k; ++d)
    os << "      case " << d << ":\n        _continued_row" << d << "(q, v, p, out);\n"
       << "        return;\n";
  os << "      default:\n        return;\n    }\n  }\n";
}

}  // namespace

void emit_spatial(std::ostringstream& os, const CompiledModel& compiled,
                  const EmitOptions& options) {
  emit_spatial_branches(os, compiled, options.max_function_ops);
  emit_spatial_continuation(os, compiled, options.max_function_ops);
}

}  // namespace kinegen::codegen::emit_detail
