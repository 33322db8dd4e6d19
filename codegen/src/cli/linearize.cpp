// `kinegen linearize`: the exact A and B of x' = f(x, u), x = (z, zd), u the run-time inputs,
// at an operating point, as JSON or CSV.
#include "kinegen/codegen/analysis/linearize.hpp"

#include <memory>
#include <string>

#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/io/output_file.hpp"
#include "linear.hpp"

namespace kinegen::cli {

namespace {

struct LinearizeArgs {
  std::string at, format, output = "-";
};

void write_json(std::ostream& out, const kc::LinearModel& l) {
  out << "{\"t\": " << json_number(l.at.t) << ", \"states\": " << json_strings(l.states)
      << ", \"inputs\": " << json_strings(l.inputs) << ", \"x\": " << json_vector(l.x)
      << ", \"u\": " << json_vector(l.at.u) << ", \"xdot\": " << json_vector(l.xdot)
      << ", \"A\": " << json_matrix(l.a) << ", \"B\": " << json_matrix(l.b) << "}\n";
}

// [A B] as one table: each row the derivative of the state named in its first column, by the
// states and then the inputs.
void write_csv(std::ostream& out, const kc::LinearModel& l) {
  out << "state";
  for (const auto& s : l.states) out << "," << s;
  for (const auto& u : l.inputs) out << "," << u;
  out << "\n";
  for (Eigen::Index r = 0; r < l.a.rows(); ++r) {
    out << l.states[r];
    for (Eigen::Index c = 0; c < l.a.cols(); ++c) out << "," << number(l.a(r, c));
    for (Eigen::Index c = 0; c < l.b.cols(); ++c) out << "," << number(l.b(r, c));
    out << "\n";
  }
}

int run_linearize(const Common& c, const LinearizeArgs& o) {
  const std::string format = output_format(o.format, o.output, "json", {"json", "csv"});
  LinearSetup s = load_linear(c, "linearize", o.at, {"t", "z", "zd", "u"});
  const kc::LinearModel l = kc::linearize(*s.linearizer, s.at);
  kc::OutputFile file(o.output);
  if (format == "csv") {
    write_csv(file.stream(), l);
  } else {
    write_json(file.stream(), l);
  }
  file.commit();
  return 0;
}

}  // namespace

Subcommand add_linearize(CLI::App& app, Common& common) {
  const auto o = std::make_shared<LinearizeArgs>();
  auto* cmd = app.add_subcommand(
      "linearize", "Exact A and B of x' = f(x, u) at an operating point, for control");
  add_common(cmd, common);
  cmd->add_option("--at", o->at,
                  "t=T, z=Z1,..., zd=V1,..., u=U1,... (defaults: t = 0, value0, v0, u = 0), or "
                  "single values by name (Z, Z.v, an input's name)");
  cmd->add_option("--format", o->format, "json (default) or csv (default from -o's extension)");
  cmd->add_option("-o,--output", o->output, "Output file (default: standard output)");
  return {cmd, [&common, o] { return run_linearize(common, *o); }};
}

}  // namespace kinegen::cli
