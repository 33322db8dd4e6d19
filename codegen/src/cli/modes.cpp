// `kinegen modes`: small oscillations about the equilibrium (docs/format.md, Equilibrium and small
// oscillations): M_z, K_z, C_z, the natural frequencies (damped ones with their damping ratios) and
// the mode shapes as dq of every coordinate, as text or as JSON that `kinegen view --modes` plays.
#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "kinegen/codegen/analysis/equilibrium.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/base/log.hpp"
#include "kinegen/codegen/io/output_file.hpp"
#include "linear.hpp"

namespace kinegen::cli {

namespace {

struct ModesArgs {
  std::string at, format, output = "-";
};

std::string matrix_text(const Eigen::MatrixXd& m) {
  std::string s = "[";
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    s += r ? "; " : "";
    for (Eigen::Index c = 0; c < m.cols(); ++c) s += (c ? " " : "") + number(m(r, c));
  }
  return s + "]";
}

void write_text(std::ostream& out, const kc::Mechanism& m, const kc::ModalAnalysis& a,
                bool equilibrium) {
  const auto names = kc::state_names(m);
  std::string at;
  for (Eigen::Index k = 0; k < a.at.z.size(); ++k)
    at += (k ? ", " : "") + names[k] + " = " + number(a.at.z[k]);
  out << "modes of " << m.name << " at " << kc::format_time(a.at.t) << ", " << at
      << (equilibrium ? " (the equilibrium): " : ": ") << kc::to_string(a.stability) << "\n";
  out << "M_z = " << matrix_text(a.stiffness.mass) << "\n";
  out << "K_z = " << matrix_text(a.stiffness.stiffness) << "\n";
  if (a.damped) out << "C_z = " << matrix_text(a.stiffness.damping) << "\n";
  const auto labels = kc::coordinate_labels(m);
  for (std::size_t k = 0; k < a.modes.size(); ++k) {
    const kc::Mode& mode = a.modes[k];
    out << "mode " << k + 1 << ": ";
    if (mode.kind == kc::Stability::kUnstable) out << "unstable (it grows)";
    if (mode.kind == kc::Stability::kNeutral) out << "neutral (zero stiffness)";
    if (mode.kind == kc::Stability::kStable && mode.frequency == 0) out << "overdamped (it decays)";
    if (mode.frequency > 0) {
      // A growing oscillation has a frequency too (a negative damping ratio).
      out << (mode.kind == kc::Stability::kStable ? "" : ", ") << number(mode.frequency) << " Hz";
      if (a.damped)
        out << ", damping ratio " << number(mode.damping_ratio) << ", damped "
            << number(mode.damped_frequency) << " Hz";
    }
    out << "; dz:";
    for (Eigen::Index j = 0; j < mode.dz.size(); ++j)
      out << " " << names[j] << " " << number(mode.dz[j]);
    out << "; dq:";
    for (std::size_t j = 0; j < labels.size(); ++j)
      out << " " << labels[j] << " " << number(mode.dq[j]);
    out << "\n";
  }
}

void write_json(std::ostream& out, const kc::Mechanism& m, const kc::ModalAnalysis& a,
                bool equilibrium) {
  const auto names = kc::state_names(m);
  const std::vector<std::string> free(names.begin(), names.begin() + a.at.z.size());
  const auto field = [&](auto get) {
    Eigen::VectorXd v(a.modes.size());
    for (std::size_t k = 0; k < a.modes.size(); ++k) v[k] = get(a.modes[k]);
    return json_vector(v);
  };
  std::vector<std::string> kinds;
  std::string shapes = "[", shapes_z = "[";
  for (std::size_t k = 0; k < a.modes.size(); ++k) {
    kinds.push_back(kc::to_string(a.modes[k].kind));
    shapes += (k ? ", " : "") + json_vector(a.modes[k].dq);
    shapes_z += (k ? ", " : "") + json_vector(a.modes[k].dz);
  }
  out << "{\"coordinates\": " << json_strings(kc::coordinate_labels(m))
      << ", \"q\": " << json_vector(a.state.q)
      << ", \"frequencies\": " << field([](const kc::Mode& x) { return x.frequency; })
      << ", \"shapes\": " << shapes << "]"
      << ", \"t\": " << json_number(a.at.t)
      << ", \"equilibrium\": " << (equilibrium ? "true" : "false") << ", \"stability\": \""
      << kc::to_string(a.stability) << "\", \"free\": " << json_strings(free)
      << ", \"z\": " << json_vector(a.at.z) << ", \"mass\": " << json_matrix(a.stiffness.mass)
      << ", \"stiffness\": " << json_matrix(a.stiffness.stiffness)
      << ", \"damping\": " << json_matrix(a.stiffness.damping)
      << ", \"damped_frequencies\": " << field([](const kc::Mode& x) { return x.damped_frequency; })
      << ", \"damping_ratios\": " << field([](const kc::Mode& x) { return x.damping_ratio; })
      << ", \"kinds\": " << json_strings(kinds) << ", \"shapes_z\": " << shapes_z << "]}\n";
}

int run_modes(const Common& c, const ModesArgs& o) {
  const std::string format = output_format(o.format, o.output, "text", {"text", "json"});
  LinearSetup s = load_linear(c, "modes", o.at, {"t", "z", "u"});
  // With z in --at, the modes there; else about the equilibrium found from value0.
  kc::OperatingPoint unset = s.at;
  unset.z.setConstant(std::numeric_limits<double>::quiet_NaN());
  const kc::OperatingPoint given =
      kc::parse_operating_point(s.model->mechanism(), o.at, {"t", "z", "u"}, unset);
  const bool at_equilibrium = given.z.array().isNaN().all();
  kc::OperatingPoint p = s.at;
  if (at_equilibrium) p = kc::find_equilibrium(*s.linearizer, s.at).at;
  const kc::ModalAnalysis a = kc::modal_analysis(*s.linearizer, p);
  if (!at_equilibrium) {
    // Beyond rounding only: the bound at which `equilibrium`'s Newton stops, so that the point
    // it printed is an equilibrium here too.
    const Eigen::VectorXd bound =
        kc::rest_bound(*s.linearizer, a.state, a.stiffness.mass, a.stiffness.stiffness);
    if ((a.force.cwiseAbs().array() > bound.array()).any())
      kc::Log::global().warning(s.model->mechanism().source +
                                ": --at z is not an equilibrium (B^T Q^A = " +
                                kc::format_estimate(a.force.cwiseAbs().maxCoeff()) +
                                " there): the modes are of the linearization there");
  }
  kc::OutputFile file(o.output);
  if (format == "json") {
    write_json(file.stream(), s.model->mechanism(), a, at_equilibrium);
  } else {
    write_text(file.stream(), s.model->mechanism(), a, at_equilibrium);
  }
  file.commit();
  return 0;
}

}  // namespace

Subcommand add_modes(CLI::App& app, Common& common) {
  const auto o = std::make_shared<ModesArgs>();
  auto* cmd = app.add_subcommand(
      "modes", "Natural frequencies and mode shapes about the equilibrium (or --at z=...)");
  add_common(cmd, common);
  cmd->add_option("--at", o->at,
                  "t=T, z=Z1,... (default: the equilibrium found from value0) and the run-time "
                  "inputs u=U1,..., or single values by name");
  cmd->add_option("--format", o->format,
                  "text (default) or json (kinegen view --modes reads it; default from -o's "
                  "extension)");
  cmd->add_option("-o,--output", o->output, "Output file (default: standard output)");
  return {cmd, [&common, o] { return run_modes(common, *o); }};
}

}  // namespace kinegen::cli
