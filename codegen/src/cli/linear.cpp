// What equilibrium, modes and linearize share (see linear.hpp).
#include "linear.hpp"

#include <algorithm>
#include <cmath>

#include "kinegen/codegen/base/format.hpp"

namespace kinegen::cli {

LinearSetup load_linear(const Common& c, const std::string& command, const std::string& at,
                        const std::vector<std::string>& keys) {
  kc::BuildOptions build;
  build.free_as_state = true;
  LinearSetup s;
  // The run-time inputs stay inputs (u), as a generated header's Params holds them.
  s.model = load(c, build, false);
  const kc::Mechanism& m = s.model->mechanism();
  const int nf = m.num_free();
  if (nf == 0)
    throw kc::UsageError("`kinegen " + command +
                         "` needs free coordinates (`free:` lists the degrees of "
                         "freedom that the forces move), and the file has none");
  // --at read once with zeros, so that a bad name or count is reported before any solve.
  kc::OperatingPoint zero;
  zero.z = zero.zd = Eigen::VectorXd::Zero(nf);
  zero.u = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(kc::run_inputs(m).size()));
  const kc::OperatingPoint first = kc::parse_operating_point(m, at, keys, zero);
  s.forces = std::make_unique<kc::ForceModel>(kc::derive_forces(*s.model));
  s.linearizer = std::make_unique<kc::Linearizer>(*s.model, *s.forces, first.t);
  s.at = kc::parse_operating_point(m, at, keys, s.linearizer->initial());
  return s;
}

std::string output_format(const std::string& format, const std::string& output,
                          const std::string& fallback, const std::vector<std::string>& allowed) {
  std::string f = format;
  const auto ends = [&](const char* ext) {
    const std::string e(ext);
    return output.size() > e.size() && output.compare(output.size() - e.size(), e.size(), e) == 0;
  };
  if (f.empty()) f = ends(".json") ? "json" : ends(".csv") ? "csv" : fallback;
  if (std::find(allowed.begin(), allowed.end(), f) == allowed.end()) {
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
    throw kc::UsageError("--format " + f + " is not one of " + list);
  }
  return f;
}

std::string number(double v) { return kc::format_number(v + 0.0); }

std::string json_number(double v) { return std::isfinite(v) ? number(v) : "null"; }

std::string json_vector(const Eigen::VectorXd& v) {
  std::string s = "[";
  for (Eigen::Index k = 0; k < v.size(); ++k) s += (k ? ", " : "") + json_number(v[k]);
  return s + "]";
}

std::string json_matrix(const Eigen::MatrixXd& m) {
  std::string s = "[";
  for (Eigen::Index r = 0; r < m.rows(); ++r)
    s += (r ? ", " : "") + json_vector(m.row(r).transpose());
  return s + "]";
}

std::string json_strings(const std::vector<std::string>& names) {
  std::string s = "[";
  for (std::size_t k = 0; k < names.size(); ++k) s += (k ? ", \"" : "\"") + names[k] + "\"";
  return s + "]";
}

std::string json_object(const std::vector<std::string>& names, const Eigen::VectorXd& v) {
  std::string s = "{";
  for (std::size_t k = 0; k < names.size(); ++k)
    s += (k ? ", \"" : "\"") + names[k] + "\": " + json_number(v[static_cast<Eigen::Index>(k)]);
  return s + "}";
}

}  // namespace kinegen::cli
