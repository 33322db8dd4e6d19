// `kinegen equilibrium`: where the mechanism comes to rest under its loads (docs/format.md,
// Equilibrium and small oscillations): by default where the overdamped release from value0 (or
// --from) comes to rest, with --nearest Newton's nearest root; z, q and the joint reactions
// there, and whether it is stable.
#include "kinegen/codegen/analysis/equilibrium.hpp"

#include <memory>
#include <sstream>
#include <string>

#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/io/output_file.hpp"
#include "linear.hpp"

namespace kinegen::cli {

namespace {

struct EquilibriumArgs {
  std::string at, from, format, output = "-";
  bool nearest = false;
};

std::string verdict(const kc::ReducedStiffness& r) {
  std::string s = kc::to_string(r.stability);
  const auto along = [](const std::vector<std::string>& d) {
    std::string out;
    for (const auto& x : d) out += (out.empty() ? "" : "; ") + x;
    return out;
  };
  if (r.stability == kc::Stability::kStable)
    s += ": the reduced stiffness K_z is positive definite";
  if (!r.unstable.empty()) s += ": negative stiffness along " + along(r.unstable);
  if (!r.neutral.empty())
    s += std::string(r.unstable.empty() ? ":" : ";") + " zero stiffness (K_z singular) along " +
         along(r.neutral);
  if (!r.symmetric) s += " (K_z is not symmetric: loads that are not conservative)";
  return s;
}

void write_text(std::ostream& out, const kc::Mechanism& m, const kc::Equilibrium& e,
                const std::vector<std::string>& force_names, const std::vector<double>& forces) {
  const auto free = kc::state_names(m);
  out << "equilibrium of " << m.name << " at " << kc::format_time(e.at.t) << " (";
  if (e.left_start) out << "the start is not stable: left along its most unstable direction, ";
  if (e.flow_steps > 0)
    out << "released: " << e.flow_steps << " step" << (e.flow_steps == 1 ? "" : "s")
        << " of the overdamped flow, then ";
  out << e.iterations << " Newton step" << (e.iterations == 1 ? "" : "s")
      << "): " << verdict(e.stiffness) << "\n";
  for (Eigen::Index k = 0; k < e.at.z.size(); ++k)
    out << free[k] << " = " << number(e.at.z[k]) << "\n";
  out << "stiffness eigenvalues (K_z v = lambda M_z v):";
  for (double v : e.stiffness.eigenvalues) out << " " << number(v);
  out << "\n";
  const auto labels = kc::coordinate_labels(m);
  for (std::size_t k = 0; k < labels.size(); ++k)
    out << labels[k] << " = " << number(e.state.q[k]) << "\n";
  for (std::size_t k = 0; k < force_names.size(); ++k)
    out << force_names[k] << " = " << number(forces[k]) << "\n";
}

void write_json(std::ostream& out, const kc::Mechanism& m, const kc::Equilibrium& e,
                const std::vector<std::string>& force_names, const std::vector<double>& forces) {
  const auto free = kc::state_names(m);
  const std::vector<std::string> z_names(free.begin(), free.begin() + e.at.z.size());
  const kc::ReducedStiffness& r = e.stiffness;
  out << "{\"t\": " << json_number(e.at.t) << ", \"stability\": \"" << kc::to_string(r.stability)
      << "\", \"iterations\": " << e.iterations << ", \"flow_steps\": " << e.flow_steps
      << ", \"left_start\": " << (e.left_start ? "true" : "false")
      << ", \"free\": " << json_strings(z_names) << ", \"z\": " << json_vector(e.at.z)
      << ", \"coordinates\": " << json_strings(kc::coordinate_labels(m))
      << ", \"q\": " << json_vector(e.state.q) << ", \"forces\": "
      << json_object(force_names, Eigen::Map<const Eigen::VectorXd>(
                                      forces.data(), static_cast<Eigen::Index>(forces.size())))
      << ", \"mass\": " << json_matrix(r.mass) << ", \"stiffness\": " << json_matrix(r.stiffness)
      << ", \"stiffness_eigenvalues\": " << json_vector(r.eigenvalues)
      << ", \"unstable\": " << json_strings(r.unstable)
      << ", \"neutral\": " << json_strings(r.neutral) << ", \"residual\": " << json_vector(e.force)
      << "}\n";
}

void write_csv(std::ostream& out, const kc::Mechanism& m, const kc::Equilibrium& e,
               const std::vector<std::string>& force_names, const std::vector<double>& forces) {
  const auto free = kc::state_names(m);
  std::ostringstream header, row;
  header << "t";
  row << number(e.at.t);
  for (Eigen::Index k = 0; k < e.at.z.size(); ++k) {
    header << "," << free[k];
    row << "," << number(e.at.z[k]);
  }
  const auto labels = kc::coordinate_labels(m);
  for (std::size_t k = 0; k < labels.size(); ++k) {
    header << "," << labels[k];
    row << "," << number(e.state.q[k]);
  }
  for (std::size_t k = 0; k < force_names.size(); ++k) {
    header << "," << force_names[k];
    row << "," << number(forces[k]);
  }
  out << header.str() << "\n" << row.str() << "\n";
}

int run_equilibrium(const Common& c, const EquilibriumArgs& o) {
  const std::string format = output_format(o.format, o.output, "text", {"text", "csv", "json"});
  LinearSetup s = load_linear(c, "equilibrium", o.at, {"t", "u"});
  const kc::OperatingPoint start =
      kc::parse_operating_point(s.model->mechanism(), o.from, {"z"}, s.at, "--from");
  const kc::Equilibrium e = kc::find_equilibrium(
      *s.linearizer, start,
      o.nearest ? kc::EquilibriumSearch::kNearest : kc::EquilibriumSearch::kRest);
  // The reactions (the forces columns of `analyze --forces`) at rest there, the run-time inputs as
  // given.
  kc::ForceSolver solver(*s.model, *s.forces);
  solver.set_inputs(s.linearizer->dynamics().input_slots());
  std::vector<double> forces;
  if (!solver.solve(e.at.t, e.state.q, e.state.qd, e.state.qdd, forces))
    throw kc::AnalysisError(s.model->mechanism().source +
                            ": the reactions at the equilibrium do not solve: Phi_q^T is "
                            "singular there");
  const auto force_names = kc::force_columns(s.model->mechanism());
  kc::OutputFile file(o.output);
  std::ostream& out = file.stream();
  if (format == "json") {
    write_json(out, s.model->mechanism(), e, force_names, forces);
  } else if (format == "csv") {
    write_csv(out, s.model->mechanism(), e, force_names, forces);
  } else {
    write_text(out, s.model->mechanism(), e, force_names, forces);
  }
  file.commit();
  return 0;
}

}  // namespace

Subcommand add_equilibrium(CLI::App& app, Common& common) {
  const auto o = std::make_shared<EquilibriumArgs>();
  auto* cmd = app.add_subcommand(
      "equilibrium", "Where the free coordinates come to rest, the reactions, the stability");
  add_common(cmd, common);
  cmd->add_option("--at", o->at,
                  "t=T and the run-time inputs u=U1,... (or by name) to hold (default t = 0, "
                  "u = 0)");
  cmd->add_option("--from", o->from,
                  "The start: z=Z1,... or free coordinates by name, Z=V,... (default: the free "
                  "items' value0)");
  cmd->add_flag("--nearest", o->nearest,
                "Newton's nearest root of B^T Q^A = 0 from the start, whatever its stability "
                "(default: where the overdamped release from the start comes to rest)");
  cmd->add_option("--format", o->format,
                  "text (default), csv or json (default from -o's extension)");
  cmd->add_option("-o,--output", o->output, "Output file (default: standard output)");
  return {cmd, [&common, o] { return run_equilibrium(common, *o); }};
}

}  // namespace kinegen::cli
