#include "kinegen/codegen/analysis/sensitivity.hpp"

#include <algorithm>
#include <cmath>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/analysis/suspension.hpp"
#include "kinegen/codegen/constraints/registry.hpp"

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

namespace {

// d(A(p) s)/dp along dp, of the homogeneous A(p) = (e0^2 - e.e) I + 2 e e^T + 2 e0 e~: exact,
// so a dp that keeps |p| to first order (the normalization rows' solve) turns s rigidly.
Eigen::Vector3d rotated_derivative(const Eigen::Vector4d& p, const Eigen::Vector4d& dp,
                                   const Eigen::Vector3d& s) {
  const double e0 = p[0], d0 = dp[0];
  const Eigen::Vector3d e = p.tail<3>(), de = dp.tail<3>();
  return 2 * ((e0 * d0 - e.dot(de)) * s + de * e.dot(s) + e * de.dot(s) + d0 * e.cross(s) +
              e0 * de.cross(s));
}

Eigen::Vector3d rotated(const Eigen::Vector4d& p, const Eigen::Vector3d& s) {
  const double e0 = p[0];
  const Eigen::Vector3d e = p.tail<3>();
  return (e0 * e0 - e.squaredNorm()) * s + 2 * e * e.dot(s) + 2 * e0 * e.cross(s);
}

// The spatial points' and vectors' d s'/dp (SensitivityModel::ds3), from the symbolic offsets
// in the parameters.
void offset_derivatives(const CompiledModel& model, SensitivityModel& s) {
  const SymbolTable& symbols = model.symbols();
  const auto& values = model.symbolic().param_values;
  s.local3 = spatial_offsets(model);
  for (int p : s.params) {
    std::vector<Eigen::Vector3d> ds;
    for (const auto* list : {&model.symbolic().point_s3, &model.symbolic().vectors3})
      for (const auto& v : *list) {
        const auto d = [&](int c) {
          return to_double(substitute_params(v[c].diff(symbols.param(p)), symbols, values));
        };
        ds.emplace_back(d(0), d(1), d(2));
      }
    s.ds3.push_back(std::move(ds));
  }
}

// Some spatial constraints hold numbers taken at the q0 pose (docs/format.md, Spatial
// mechanisms): a revolute_angle's f_j and a translational's default ref_j (from the axes and
// the bodies' rotations there), a fixed joint's frame and default sj (from the bodies' poses and
// si). Phi_p treats them as constants, so a parameter that moves them would get a derivative
// that misses their motion: refused, naming the item.
void refuse_carried_parameters(const CompiledModel& model, const std::vector<int>& params) {
  const Mechanism& m = model.mechanism();
  const SymbolTable& symbols = model.symbols();
  const auto& values = model.symbolic().param_values;
  const auto& q0 = model.symbolic().q0;
  for (const Constraint* item : m.constraints()) {
    const std::string type = item->type_name();
    const Constraint* c = item;
    if (type == "revolute_angle")
      c = &m.joints[item->joint];
    else if (type != "translational" && type != "fixed")
      continue;
    const EquationContext context(*c, m, symbols, values);
    std::vector<GiNaC::ex> reads;
    const auto pose = [&](int body, int from) {
      for (int k = from; body != kGround && k < 7; ++k) reads.push_back(q0[7 * body + k]);
    };
    const bool fixed = type == "fixed";
    pose(c->i, fixed ? 0 : 3);
    pose(c->j, fixed ? 0 : 3);
    for (const char* key : {"axis_i", "axis_j", "ref_i", "si"}) {
      if (!c->vectors.count(key) || c->vector(key).x.text.empty()) continue;
      if ((std::string(key) == "si") != fixed) continue;
      for (const auto& e : context.vector3(key)) reads.push_back(e);
    }
    for (int p : params)
      for (const auto& e : reads)
        if (e.has(symbols.param(p)))
          throw InputError(m.source, item->item, item->loc,
                           "the sensitivity to '" + symbols.param_name(p) +
                               "' is not computed: it moves what this " + type +
                               " takes from the q0 pose as a constant (the axes, a body's r0 "
                               "or rotation)");
  }
}

// A suspension's wheel_travel and track_change are differences from the design position
// (analysis/suspension.hpp), so their d/dp subtract the d/dp there.
void design_offsets(const CompiledModel& model, SensitivityModel& s) {
  const int first = model.mechanism().suspension->first_output;
  const double t = model.symbolic().design_t;
  AnalysisOptions options;
  options.sensitivity = &s;
  options.warn = [](const std::string&) {};
  Eigen::MatrixXd at_design;
  try {
    run_analysis(
        model, {t, t, 0}, [&](const StateRow& row) { at_design = row.doutputs_dp; }, options);
  } catch (const AnalysisError& e) {
    throw AnalysisError(std::string(e.what()) + " (solving the suspension's design position, " +
                        "design_t = " + format_number(t) + ", for the sensitivities)");
  }
  s.output_offsets = Eigen::MatrixXd::Zero(at_design.rows(), at_design.cols());
  for (int o : {first + SuspensionRows::kWheelTravel, first + SuspensionRows::kTrackChange})
    s.output_offsets.row(o) = at_design.row(o);
}

}  // namespace

std::vector<Eigen::Vector3d> spatial_offsets(const CompiledModel& model) {
  std::vector<Eigen::Vector3d> out;
  if (!model.mechanism().spatial) return out;
  const auto number = [&](const GiNaC::ex& e) {
    return to_double(substitute_params(e, model.symbols(), model.symbolic().param_values));
  };
  for (const auto* list : {&model.symbolic().point_s3, &model.symbolic().vectors3})
    for (const auto& v : *list) out.emplace_back(number(v[0]), number(v[1]), number(v[2]));
  return out;
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
  if (model.mechanism().spatial) refuse_carried_parameters(model, s.params);
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
  if (model.mechanism().spatial) offset_derivatives(model, s);
  if (outputs && model.mechanism().suspension) design_offsets(model, s);
  return s;
}

void point_sensitivities(const CompiledModel& model, const SensitivityModel& sensitivity,
                         const Eigen::VectorXd& q, const Eigen::MatrixXd& dq_dp,
                         Eigen::MatrixXd& dpoints) {
  const auto& points = model.mechanism().points;
  const int np = static_cast<int>(sensitivity.params.size());
  if (model.mechanism().spatial) {
    // Per point, then per vector: dr/dp + d(A s')/dp + A ds'/dp (no r for a vector).
    const auto& m = model.mechanism();
    const auto n = static_cast<Eigen::Index>(sensitivity.local3.size());
    dpoints.resize(3 * n, np);
    for (Eigen::Index i = 0; i < n; ++i) {
      const bool point = i < static_cast<Eigen::Index>(points.size());
      const int body = point ? points[i].body : m.vectors[i - points.size()].body;
      for (int k = 0; k < np; ++k) {
        Eigen::Vector3d d = sensitivity.ds3[k][i];
        if (body >= 0) {
          const Eigen::Vector4d p = q.segment<4>(7 * body + 3);
          d = rotated(p, d) +
              rotated_derivative(p, dq_dp.block<4, 1>(7 * body + 3, k), sensitivity.local3[i]);
          if (point) d += dq_dp.block<3, 1>(7 * body, k);
        }
        dpoints.block<3, 1>(3 * i, k) = d.array() + 0.0;  // -0 prints as 0
      }
    }
    return;
  }
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
      doutputs(o, k) = values[k * n + o] + o_q.row(o).dot(dq_dp.col(k)) -
                       (sensitivity.output_offsets.size() ? sensitivity.output_offsets(o, k) : 0) +
                       0.0;  // -0 prints as 0
}

std::vector<std::string> position_quantities(const Mechanism& m) {
  std::vector<std::string> quantities = coordinate_labels(m);
  if (!m.spatial) {
    for (const auto& p : m.points)
      for (const char* c : {".x", ".y"}) quantities.push_back(p.name + c);
    return quantities;
  }
  for (const auto* list : {&m.points, &m.vectors})
    for (const auto& p : *list)
      for (const char* c : {".x", ".y", ".z"}) quantities.push_back(p.name + c);
  return quantities;
}

Eigen::VectorXd position_values(const Mechanism& m, const std::vector<Eigen::Vector3d>& offsets,
                                const StateRow& row) {
  if (!m.spatial) {
    Eigen::VectorXd v(row.q.size() + 2 * static_cast<Eigen::Index>(row.points.size()));
    v.head(row.q.size()) = row.q;
    for (std::size_t p = 0; p < row.points.size(); ++p)
      v.segment<2>(row.q.size() + 2 * p) = row.points[p].r;
    return v;
  }
  const auto n = static_cast<Eigen::Index>(offsets.size());
  Eigen::VectorXd v(row.q.size() + 3 * n);
  v.head(row.q.size()) = row.q;
  for (Eigen::Index i = 0; i < n; ++i) {
    const bool point = i < static_cast<Eigen::Index>(m.points.size());
    const int body = point ? m.points[i].body : m.vectors[i - m.points.size()].body;
    Eigen::Vector3d x = offsets[i];
    if (body >= 0) {
      x = rotated(row.q.segment<4>(7 * body + 3), x);
      if (point) x += row.q.segment<3>(7 * body);
    }
    v.segment<3>(row.q.size() + 3 * i) = x;
  }
  return v;
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
