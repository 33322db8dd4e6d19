#include "kinegen/codegen/analysis/sensitivity.hpp"

#include <algorithm>
#include <cmath>

#include "kinegen/codegen/analysis/evaluator.hpp"

namespace kinegen::codegen {

std::vector<std::string> split_parameter_list(const std::string& list) {
  std::vector<std::string> names;
  std::size_t begin = 0;
  while (true) {
    const std::size_t end = list.find(',', begin);
    std::string name = list.substr(begin, end == std::string::npos ? end : end - begin);
    if (name.empty())
      throw UsageError("--sensitivity expects parameter names separated by commas, got '" + list +
                       "'");
    names.push_back(std::move(name));
    if (end == std::string::npos) break;
    begin = end + 1;
  }
  return names;
}

int find_parameter(const CompiledModel& model, const std::string& name, const std::string& option) {
  const SymbolTable& symbols = model.symbols();
  for (int k = 0; k < symbols.num_params(); ++k)
    if (symbols.param_name(k) == name) return k;
  std::string known;
  for (int k = 0; k < symbols.num_params(); ++k)
    known += (known.empty() ? "" : ", ") + symbols.param_name(k);
  throw UsageError(option + ": the mechanism has no parameter '" + name +
                   "' (it has: " + (known.empty() ? "none" : known) + ")");
}

SensitivityModel build_sensitivity(const CompiledModel& model,
                                   const std::vector<std::string>& names, bool outputs) {
  const SymbolTable& symbols = model.symbols();
  SensitivityModel s;
  for (const auto& name : names) {
    // A repeated name would repeat column names, which a reader keyed on names collapses.
    if (std::find(s.names.begin(), s.names.end(), name) != s.names.end())
      throw UsageError("--sensitivity: '" + name + "' is given twice");
    s.params.push_back(find_parameter(model, name, "--sensitivity"));
    s.names.push_back(name);
  }
  // d(O)/d(p) of an output that reads velocities would need dqd/dp, which is not computed:
  // refused rather than written as the partial derivative at fixed qd.
  const auto& items = model.mechanism().outputs;
  for (std::size_t o = 0; outputs && o < items.size(); ++o)
    if (model.symbolic().output_reads_velocity[o])
      throw InputError(model.mechanism().source, "outputs." + items[o].name, items[o].loc,
                       "--sensitivity: the output reads velocities, and only positions' "
                       "sensitivities are computed (remove the output or --sensitivity)");
  s.outputs = outputs;
  const ParameterPrograms& programs = model.parameter_programs(s.params, outputs);
  s.phi_p = programs.phi_p;
  const auto& values = model.symbolic().param_values;
  for (int p : s.params) {
    std::vector<Eigen::Vector2d> ds;
    for (const auto& [x, y] : model.symbolic().point_s)
      ds.emplace_back(to_double(substitute_params(x.diff(symbols.param(p)), symbols, values)),
                      to_double(substitute_params(y.diff(symbols.param(p)), symbols, values)));
    s.point_ds.push_back(std::move(ds));
  }
  if (outputs) s.output_p = programs.output_p;
  return s;
}

void point_sensitivities(const CompiledModel& model, const SensitivityModel& sensitivity,
                         const Eigen::VectorXd& q, const Eigen::MatrixXd& dq_dp,
                         Eigen::MatrixXd& dpoints) {
  const auto& points = model.mechanism().points;
  const int np = static_cast<int>(sensitivity.params.size());
  dpoints.resize(2 * static_cast<Eigen::Index>(points.size()), np);
  for (std::size_t p = 0; p < points.size(); ++p) {
    const int b = 3 * points[p].body;
    const double c = std::cos(q[b + 2]), sn = std::sin(q[b + 2]);
    const Eigen::Matrix2d a{{c, -sn}, {sn, c}};
    const Eigen::Vector2d as = a * model.point_offsets()[p];
    const Eigen::Vector2d as_perp(-as[1], as[0]);  // d(A s)/dphi
    for (int k = 0; k < np; ++k)
      dpoints.block<2, 1>(2 * p, k) =
          dq_dp.block<2, 1>(b, k) + dq_dp(b + 2, k) * as_perp + a * sensitivity.point_ds[k][p];
    dpoints.array() += 0.0;  // -0 prints as 0
  }
}

void output_sensitivities(const CompiledModel& model, const SensitivityModel& sensitivity, double t,
                          const Eigen::VectorXd& q, const Eigen::MatrixXd& dq_dp,
                          Eigen::MatrixXd& doutputs) {
  const int n = sensitivity.outputs ? model.programs().num_outputs : 0, nq = model.nq();
  const int np = static_cast<int>(sensitivity.params.size());
  doutputs.resize(n, np);
  if (n == 0) return;
  // Runs per row; outputs are few, so the work space is small next to the solve.
  std::vector<double> values(static_cast<std::size_t>(n) * (np + nq));
  ProgramEvaluator<double>(sensitivity.output_p)
      .run(q.data(), nullptr, t, model.params().data(), values.data());
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>
      o_q(values.data() + static_cast<std::size_t>(n) * np, n, nq);
  for (int k = 0; k < np; ++k)
    for (int o = 0; o < n; ++o)
      doutputs(o, k) = values[k * n + o] + o_q.row(o).dot(dq_dp.col(k)) + 0.0;  // -0 prints as 0
}

std::vector<std::string> position_quantities(const Mechanism& m) {
  std::vector<std::string> quantities = coordinate_labels(m);
  for (const auto& p : m.points)
    for (const char* c : {".x", ".y"}) quantities.push_back(p.name + c);
  return quantities;
}

std::vector<std::string> sensitivity_columns(const Mechanism& m,
                                             const std::vector<std::string>& names) {
  std::vector<std::string> quantities = position_quantities(m);
  for (const auto& o : m.outputs) quantities.push_back(o.name);
  std::vector<std::string> columns;
  for (const auto& p : names)
    for (const auto& c : quantities) columns.push_back("d(" + c + ")/d(" + p + ")");
  return columns;
}

}  // namespace kinegen::codegen
