// `kinegen eval`: Phi, Phi_q, nu, gamma (and the outputs' values) at one q, qd, t as JSON.
#include <Eigen/Dense>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "cli.hpp"
#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

namespace {

std::string json_number(double v) { return std::isfinite(v) ? kc::format_number(v) : "null"; }

std::string json_array(const Eigen::VectorXd& v) {
  std::string s = "[";
  for (int k = 0; k < v.size(); ++k) s += (k ? ", " : "") + json_number(v[k]);
  return s + "]";
}

Eigen::VectorXd vector_arg(const std::vector<double>& values, int n, const char* option) {
  if (static_cast<int>(values.size()) != n)
    throw kc::UsageError(std::string(option) + " expects " + std::to_string(n) +
                         " comma-separated values (one per coordinate), got " +
                         std::to_string(values.size()));
  return Eigen::Map<const Eigen::VectorXd>(values.data(), n);
}

struct EvalArgs {
  double t = 0;
  std::vector<double> q, qd;  // empty: q0, zeros
};

int run_eval(const Common& c, const EvalArgs& o) {
  const auto model = load(c, {}, false);
  const int nq = model->nq(), nc = model->nc();
  const Eigen::VectorXd q = o.q.empty() ? model->q0() : vector_arg(o.q, nq, "--q");
  const Eigen::VectorXd qd =
      o.qd.empty() ? Eigen::VectorXd::Zero(nq) : vector_arg(o.qd, nq, "--qd");
  const kc::EvalResult e = kc::evaluate(*model, q, qd, o.t);
  std::string rows;
  for (int r = 0; r < nc; ++r) rows += (r ? ", " : "") + json_array(e.phi_q.row(r).transpose());
  // Outputs' values; a file without outputs keeps its v1 JSON.
  const std::string outputs =
      e.outputs.size() > 0 ? ", \"outputs\": " + json_array(e.outputs) : std::string();
  kc::OutputFile out("-");
  out.stream() << "{\"phi\": " << json_array(e.phi) << ", \"phi_q\": [" << rows
               << "], \"nu\": " << json_array(e.nu) << ", \"gamma\": " << json_array(e.gamma)
               << outputs << "}\n";
  out.commit();
  return 0;
}

}  // namespace

Subcommand add_eval(CLI::App& app, Common& common) {
  const auto o = std::make_shared<EvalArgs>();
  auto* eval = app.add_subcommand("eval", "Print Phi, Phi_q, nu and gamma as JSON");
  add_common(eval, common);
  eval->add_option("--t", o->t, "Time (default 0)");
  eval->add_option("--q", o->q, "Coordinates (default: q0)")
      ->delimiter(',')
      ->allow_extra_args(false);
  eval->add_option("--qd", o->qd, "Velocities (default: zeros)")
      ->delimiter(',')
      ->allow_extra_args(false);
  return {eval, [&common, o] { return run_eval(common, *o); }};
}

}  // namespace kinegen::cli
