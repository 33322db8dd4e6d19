#include "kinegen/codegen/model.hpp"

namespace kinegen::codegen {

std::unique_ptr<CompiledModel> CompiledModel::from_file(const std::string& path,
                                                        const std::vector<ParamOverride>& overrides) {
  return from_mechanism(load_mechanism(path), overrides);
}

std::unique_ptr<CompiledModel> CompiledModel::from_mechanism(
    Mechanism mechanism, const std::vector<ParamOverride>& overrides) {
  std::unique_ptr<CompiledModel> model(new CompiledModel(std::move(mechanism)));
  model->build(overrides);
  return model;
}

void CompiledModel::build(const std::vector<ParamOverride>& overrides) {
  symbols_ = std::make_unique<SymbolTable>(mechanism_);
  symbolic_ = derive(mechanism_, *symbols_, overrides);
  programs_ = lower_model(symbolic_, *symbols_, mechanism_.nq());
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

std::string CompiledModel::row_label(int row) const {
  const RowOrigin& o = symbolic_.rows[row];
  std::string label = o.constraint->item;
  if (o.constraint->equation_count() > 1) label += " equation " + std::to_string(o.component + 1);
  if (o.constraint->loc.line > 0) label += " (line " + std::to_string(o.constraint->loc.line) + ")";
  return label;
}

}  // namespace kinegen::codegen
