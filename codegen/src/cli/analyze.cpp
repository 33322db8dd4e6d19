// `kinegen analyze`: position, velocity and acceleration over a time grid as CSV, in double
// (block or dense solver), or in CLN arithmetic (--reference-digits); sensitivities and forces
// as extra columns.
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "cli.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

int run_analyze(const Common& c, double t0, double t1, int steps, const std::string& output,
                int reference_digits, bool strict, const std::string& sensitivity_list,
                bool with_forces, const std::string& solver) {
  auto model = load(c);
  kc::require_driven(*model);
  check_grid(t0, t1, steps);
  if (reference_digits != 0 &&
      (reference_digits < kc::kMinReferenceDigits || reference_digits > kc::kMaxReferenceDigits))
    throw kc::UsageError("--reference-digits must be between " +
                         std::to_string(kc::kMinReferenceDigits) + " and " +
                         std::to_string(kc::kMaxReferenceDigits));
  kc::SensitivityModel sensitivity;
  if (!sensitivity_list.empty()) {
    if (reference_digits != 0)
      throw kc::UsageError("--sensitivity is not available with --reference-digits");
    const auto names = kc::split_parameter_list(sensitivity_list);
    // Naming a derived parameter treats it as overridden (spec 6.6).
    if (auto base = model->with_base_parameters(names)) model = std::move(base);
    sensitivity = kc::build_sensitivity(*model, names);
  }
  // Forces: every input error (masses, loads) before any output.
  std::unique_ptr<kc::ForceModel> forces;
  std::vector<std::string> force_names;
  if (with_forces) {
    forces = std::make_unique<kc::ForceModel>(kc::forces_for_analysis(*model, t0));
    force_names = kc::force_columns(model->mechanism());
  }
  kc::OutputFile file(output.empty() ? "-" : output);
  std::ostream& out = file.stream();
  out << kc::csv_header(model->mechanism(), force_names, sensitivity.names);
  int status = 0;
  int rows = 0;
  try {
    const auto sink = [&](const kc::StateRow& row) {
      out << kc::csv_row(row, static_cast<int>(model->mechanism().bodies.size()));
      file.check();  // a full disk or a closed pipe ends the run now, not after it
      ++rows;
    };
    if (reference_digits != 0 && forces) {
      // The forces of the reference come from its own high-precision rows.
      kc::ReferenceForces reference(*model, *forces, reference_digits);
      kc::run_reference_analysis_exact(*model, {t0, t1, steps}, reference_digits,
                                       [&](const kc::ReferenceRow& exact) {
                                         kc::StateRow row = kc::to_state_row(exact);
                                         for (const auto& v : reference.solve(exact))
                                           row.forces.push_back(v.to_double());
                                         sink(row);
                                       });
    } else if (reference_digits != 0) {
      kc::run_reference_analysis(*model, {t0, t1, steps}, reference_digits, sink);
    } else {
      kc::AnalysisOptions options;
      options.strict = strict;
      options.block_solver = solver != "dense";
      if (!sensitivity_list.empty()) options.sensitivity = &sensitivity;
      options.forces = forces.get();
      options.warn = [](const std::string& w) { std::cerr << "warning: " << one_line(w) << "\n"; };
      kc::run_analysis(*model, {t0, t1, steps}, sink, options);
    }
  } catch (const kc::AnalysisError& e) {
    std::cerr << "error: " << one_line(e.what()) << "\n";
    status = kExitFailed;  // the rows solved so far are kept
  }
  // Nothing solved: a file is left as it was; standard output gets the header, as before.
  if (rows > 0 || status == 0 || !file.replaces_target()) file.commit();
  return status;
}

}  // namespace kinegen::cli
