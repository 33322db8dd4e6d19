// `kinegen analyze`: position, velocity and acceleration over a time grid as CSV, in double
// (block or dense solver), or in CLN arithmetic (--reference-digits); sensitivities and forces
// as extra columns.
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "cli.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/analysis_rows.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

namespace {

struct AnalyzeArgs {
  double t0 = 0, t1 = 0;
  int steps = 0;
  std::string output;  // empty: standard output
  int reference_digits = 0;
  bool strict = false;
  std::string sensitivity_list;
  std::string solver = "block";
  bool with_forces = false;
};

// What analyze cannot do on a spatial file yet (docs/format.md, Spatial mechanisms).
void refuse_spatial_options(const Common& c, const AnalyzeArgs& o, const kc::CompiledModel& m) {
  if (!m.mechanism().spatial) return;
  for (const auto& [given, option] : {std::pair{o.with_forces, "--forces"},
                                      std::pair{o.reference_digits != 0, "--reference-digits"}})
    if (given)
      throw kc::InputError(c.file, "space", m.mechanism().space_loc,
                           std::string("spatial files (space: 3d) are not supported by "
                                       "`kinegen analyze ") +
                               option + "` yet");
}

// The CSV's lines (analysis_rows.hpp: spatial files' 3D columns, a suspension's offsets and
// motion ratios), each written as it comes: a full disk or a closed pipe ends the run now.
class RowWriter {
 public:
  RowWriter(const kc::CompiledModel& model, const AnalyzeArgs& o)
      : rows_(model, options(o), o.steps + 1LL, "analyze") {}
  std::string header(const std::vector<std::string>& forces,
                     const std::vector<std::string>& sensitivity) const {
    return rows_.header(forces, sensitivity);
  }
  void take(const kc::StateRow& row, kc::OutputFile& file) {
    rows_.take(row, [&](const std::string& line) { write(line, file); });
  }
  void finish(kc::OutputFile& file) {
    rows_.finish([&](const std::string& line) { write(line, file); });
  }

 private:
  static kc::AnalysisOptions options(const AnalyzeArgs& o) {
    kc::AnalysisOptions options;
    options.block_solver = o.solver != "dense";
    return options;
  }
  static void write(const std::string& line, kc::OutputFile& file) {
    file.stream() << line;
    file.check();
  }
  kc::AnalysisRows rows_;
};

int run_analyze(const Common& c, const AnalyzeArgs& o) {
  auto model = load(c);
  refuse_spatial_options(c, o, *model);
  kc::require_driven(*model);
  check_grid(o.t0, o.t1, o.steps);
  if (o.reference_digits != 0 && (o.reference_digits < kc::kMinReferenceDigits ||
                                  o.reference_digits > kc::kMaxReferenceDigits))
    throw kc::UsageError("--reference-digits must be between " +
                         std::to_string(kc::kMinReferenceDigits) + " and " +
                         std::to_string(kc::kMaxReferenceDigits));
  kc::SensitivityModel sensitivity;
  if (!o.sensitivity_list.empty()) {
    if (o.reference_digits != 0)
      throw kc::UsageError("--sensitivity is not available with --reference-digits");
    const auto names = kc::split_parameter_list(o.sensitivity_list);
    // Naming a derived parameter treats it as overridden.
    if (auto base = model->with_base_parameters(names)) model = std::move(base);
    sensitivity = kc::build_sensitivity(*model, names);
  }
  // Forces: every input error (masses, loads) before any output.
  std::unique_ptr<kc::ForceModel> forces;
  std::vector<std::string> force_names;
  if (o.with_forces) {
    forces = std::make_unique<kc::ForceModel>(kc::forces_for_analysis(*model, o.t0));
    force_names = kc::force_columns(model->mechanism());
  }
  RowWriter writer(*model, o);  // solves a suspension's design position
  kc::OutputFile file(o.output.empty() ? "-" : o.output);
  file.stream() << writer.header(force_names, sensitivity.names);
  int status = 0;
  int rows = 0;
  double t_last = 0;
  try {
    const auto sink = [&](const kc::StateRow& row) {
      writer.take(row, file);
      ++rows;
      t_last = row.t;
    };
    if (o.reference_digits != 0 && forces) {
      // The forces of the reference come from its own high-precision rows.
      kc::ReferenceForces reference(*model, *forces, o.reference_digits);
      kc::run_reference_analysis_exact(*model, {o.t0, o.t1, o.steps}, o.reference_digits,
                                       [&](const kc::ReferenceRow& exact) {
                                         kc::StateRow row = kc::to_state_row(exact);
                                         for (const auto& v : reference.solve(exact))
                                           row.forces.push_back(v.to_double());
                                         sink(row);
                                       });
    } else if (o.reference_digits != 0) {
      kc::run_reference_analysis(*model, {o.t0, o.t1, o.steps}, o.reference_digits, sink);
    } else {
      kc::AnalysisOptions options;
      options.strict = o.strict;
      options.block_solver = o.solver != "dense";
      if (!o.sensitivity_list.empty()) options.sensitivity = &sensitivity;
      options.forces = forces.get();
      options.warn = warning_sink();
      kc::run_analysis(*model, {o.t0, o.t1, o.steps}, sink, options);
    }
  } catch (const kc::AnalysisError& e) {
    std::cerr << "error: " << one_line(e.what()) << "\n";
    status = kExitFailed;  // the rows solved so far are kept
  } catch (const kc::Interrupted&) {
    status = interrupted(c.file, rows, t_last);  // as a failure: the rows so far are kept
  }
  writer.finish(file);
  // Nothing solved: a file is left as it was; standard output gets the header, as before.
  if (rows > 0 || status == 0 || !file.replaces_target()) file.commit();
  return status;
}

}  // namespace

Subcommand add_analyze(CLI::App& app, Common& common) {
  const auto o = std::make_shared<AnalyzeArgs>();
  auto* analyze = app.add_subcommand("analyze", "Position, velocity and acceleration over time");
  add_common(analyze, common);
  analyze->add_option("--t0", o->t0, "Start time")->required();
  analyze->add_option("--t1", o->t1, "End time")->required();
  analyze->add_option("--steps", o->steps, "Number of steps N (N + 1 rows)")->required();
  analyze->add_option("-o,--output", o->output, "CSV file (default: standard output)");
  analyze->add_option("--reference-digits", o->reference_digits,
                      "Solve in CLN arithmetic with N decimal digits (20 to 1000) instead of "
                      "double: the high-precision reference");
  analyze->add_flag("--strict", o->strict,
                    "Redundant constraints are an error (exit 2), not a warning");
  analyze
      ->add_option("--sensitivity", o->sensitivity_list,
                   "Add d(C)/d(p) columns for these parameters (comma-separated), after all "
                   "others")
      ->type_name("P1,P2,...");
  analyze
      ->add_option("--solver", o->solver,
                   "block (default): block by block, as generated code solves, with the same "
                   "numbers; dense: Newton on all of Phi_q (sparse LU above 48 coordinates), "
                   "an independent cross-check. Redundant models always take the dense path")
      ->check(CLI::IsMember({"block", "dense"}));
  analyze->add_flag("--forces", o->with_forces,
                    "Add the drivers' efforts and the joints' reactions (masses, gravity and "
                    "forces in the file): D.effort, J.fx, J.fy, J.tz columns");
  return {analyze, [&common, o] { return run_analyze(common, *o); }};
}

}  // namespace kinegen::cli
