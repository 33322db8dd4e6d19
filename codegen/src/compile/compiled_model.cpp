#include "kinegen/codegen/compile/compiled_model.hpp"

#include <sstream>

#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/symbolic/forces.hpp"

namespace kinegen::codegen {

std::unique_ptr<CompiledModel> CompiledModel::from_file(const std::string& path,
                                                        const std::vector<ParamOverride>& overrides,
                                                        const BuildOptions& options) {
  ProgressStage stage(options.progress, "reading " + path);
  Mechanism mechanism = load_mechanism(path);
  stage.done(std::to_string(mechanism.bodies.size()) + " bodies, " +
             std::to_string(mechanism.nq()) + " coordinates, " + std::to_string(mechanism.nc()) +
             " equations");
  apply_inputs(mechanism, options.inputs, options.inputs_required, options.free_as_state);
  return from_mechanism(std::move(mechanism), overrides, options);
}

std::unique_ptr<CompiledModel> CompiledModel::from_mechanism(
    Mechanism mechanism, const std::vector<ParamOverride>& overrides,
    const BuildOptions& options) {
  if (mechanism.spatial && !options.spatial)
    throw InputError(mechanism.source, "space", mechanism.space_loc,
                     "spatial files (space: 3d) are not supported by " + options.user + " yet");
  std::unique_ptr<CompiledModel> model(new CompiledModel(std::move(mechanism)));
  model->build(overrides, options);
  return model;
}

std::vector<std::pair<std::string, double>> CompiledModel::parameter_table() const {
  std::vector<std::pair<std::string, double>> table;
  for (const Parameter& p : mechanism_.parameters) {
    const int k = symbols_->find_param(p.name);
    if (k >= 0) {
      table.emplace_back(p.name, params_[k]);
    } else if (const DerivedParameter* d = symbols_->find_derived(p.name)) {
      table.emplace_back(p.name, to_double(substitute_params(d->value, *symbols_,
                                                             symbolic_.param_values)));
    }
  }
  return table;
}

std::unique_ptr<CompiledModel> CompiledModel::with_base_parameters(
    const std::vector<std::string>& names) const {
  std::vector<ParamOverride> overrides = overrides_;
  for (const std::string& name : names) {
    const DerivedParameter* d = symbols_->find_derived(name);
    if (!d) continue;
    // Its present value, exactly (rational, or the 40 digits irrational values are kept to).
    const GiNaC::ex exact = substitute_params(d->value, *symbols_, symbolic_.param_values);
    const DigitsGuard digits(40);
    std::ostringstream value;
    value << (GiNaC::is_a<GiNaC::numeric>(exact) ? exact : GiNaC::evalf(exact));
    overrides.push_back({name, value.str()});
  }
  if (overrides.size() == overrides_.size()) return nullptr;
  return from_mechanism(mechanism_, overrides, options_);
}

void CompiledModel::build(const std::vector<ParamOverride>& overrides,
                          const BuildOptions& options) {
  std::vector<std::string> overridden;
  for (const auto& o : overrides) overridden.push_back(o.name);
  overrides_ = overrides;
  options_ = options;
  symbols_ = std::make_unique<SymbolTable>(mechanism_, overridden);
  {
    ProgressStage stage(options.progress, "deriving Phi, Phi_q, nu and gamma (" +
                                              std::to_string(mechanism_.nc()) + " equations)");
    symbolic_ = derive(mechanism_, *symbols_, overrides);
    stage.done("Phi_q: " + std::to_string(symbolic_.phi_q.size()) + " structural non-zeros");
  }
  derive_stop_when(mechanism_, *symbols_, symbolic_, force_columns(mechanism_));
  // The masses, gravity and loads are input like the rest: checked whenever the model is
  // compiled, so a bad load is an error for every command, not only with --forces.
  if (has_force_input(mechanism_.forces)) {
    ProgressStage stage(options.progress, "checking masses, gravity and loads");
    (void)derive_forces(mechanism_, *symbols_, symbolic_, mechanism_.forces);
    stage.done(std::to_string(mechanism_.forces.loads.size()) + " loads");
  }
  if (options.fold_params) {
    // Exact values, so constant subtrees still fold to one correctly rounded literal.
    ProgressStage stage(options.progress,
                        "folding " + std::to_string(symbols_->num_params()) + " parameters");
    const auto fold = [&](GiNaC::ex& e) {
      e = substitute_params(e, *symbols_, symbolic_.param_values);
    };
    for (auto& e : symbolic_.phi) fold(e);
    for (auto& e : symbolic_.phi_q) fold(e.value);
    for (auto& e : symbolic_.nu) fold(e);
    for (auto& e : symbolic_.gamma) fold(e);
    for (auto* list : {&symbolic_.output_values, &symbolic_.output_rates, &symbolic_.output_a0,
                       &symbolic_.output_q, &symbolic_.output_qd})
      for (auto& e : *list) fold(e);
    stage.done("");
  }
  // The structure stage expands single-equation blocks to find the linear ones: a row whose
  // expansion would explode is refused here, once, for every command and path.
  check_expansion_cost(mechanism_, symbolic_);
  {
    ProgressStage stage(options.progress, "lowering to straight-line code");
    programs_ = lower_model(symbolic_, *symbols_, mechanism_.nq());
    stage.done(std::to_string(programs_.phi.operation_count()) + " + " +
               std::to_string(programs_.phi_q.operation_count()) + " + " +
               std::to_string(programs_.nu.operation_count()) + " + " +
               std::to_string(programs_.gamma.operation_count()) +
               " operations (phi + phi_q + nu + gamma)");
  }
  for (const auto& v : symbolic_.param_values) params_.push_back(v.to_double());
  for (const auto& [x, y] : symbolic_.point_s)
    point_s_.emplace_back(to_double(substitute_params(x, *symbols_, symbolic_.param_values)),
                          to_double(substitute_params(y, *symbols_, symbolic_.param_values)));
}

Eigen::VectorXd CompiledModel::q0() const {
  Eigen::VectorXd q(nq());
  for (int k = 0; k < nq(); ++k)
    q[k] = to_double(substitute_params(symbolic_.q0[k], *symbols_, symbolic_.param_values));
  return q;
}

double CompiledModel::geometry_number(const Expr& e, const std::string& item) const {
  return to_double(substitute_params(symbols_->parse(e, Scope::kGeometry, item), *symbols_,
                                     symbolic_.param_values));
}

const Structure& CompiledModel::structure() const {
  if (!structure_)
    structure_ = std::make_unique<Structure>(programs_.nq == programs_.nc
                                                 ? analyze_structure(symbolic_, *symbols_)
                                                 : Structure{});
  return *structure_;
}

std::string CompiledModel::row_label(int row) const {
  const RowOrigin& o = symbolic_.rows[row];
  std::string label = o.constraint->item;
  const Constraint& c = *o.constraint;
  if (c.equation_count() > 1)
    label += c.kind->row_name ? " " + c.kind->row_name(c, o.component)
                              : " equation " + std::to_string(o.component + 1);
  if (c.loc.line > 0) label += " (line " + std::to_string(c.loc.line) + ")";
  return label;
}

}  // namespace kinegen::codegen
