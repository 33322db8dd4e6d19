// `kinegen tolerance`: worst-case and RSS deviations of the positions from parameter
// tolerances, optionally with a Monte Carlo check.
#include "kinegen/codegen/analysis/tolerance.hpp"

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "cli.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

namespace {

struct ToleranceArgs {
  kc::ToleranceOptions tolerance;
  std::string seed = "1";
  std::vector<std::string> tol;  // NAME=DELTA
  std::string output;            // empty: no CSV
};

int run_tolerance(const Common& c, const ToleranceArgs& o) {
  kc::ToleranceOptions options = o.tolerance;
  options.seed = parse_seed(o.seed, std::numeric_limits<std::uint64_t>::max());
  options.overrides = parse_overrides(c.params);
  auto model = load(c);
  kc::require_driven(*model);
  options.tolerances = kc::parse_tolerances(o.tol);
  {
    // A derived parameter with a tolerance varies on its own.
    std::vector<std::string> names;
    for (const auto& t : options.tolerances) names.push_back(t.name);
    if (auto base = model->with_base_parameters(names)) model = std::move(base);
  }
  options.progress = terminal_progress("Monte Carlo");
  options.warn = warning_sink();
  const auto result = kc::tolerance_analysis(*model, options);
  kc::OutputFile summary("-");
  summary.stream() << kc::tolerance_summary(result, options);
  summary.commit();
  if (!o.output.empty()) {
    kc::OutputFile out(o.output);
    out.stream() << kc::tolerance_csv(result);
    out.commit();
  }
  return 0;
}

}  // namespace

Subcommand add_tolerance(CLI::App& app, Common& common) {
  const auto o = std::make_shared<ToleranceArgs>();
  kc::ToleranceOptions& t = o->tolerance;
  auto* tolerance = app.add_subcommand(
      "tolerance", "Worst-case and RSS deviations of the positions from parameter tolerances");
  add_common(tolerance, common);
  tolerance->add_option("--tol", o->tol, "A parameter's tolerance: NAME=DELTA (repeatable)")
      ->type_name("NAME=DELTA")
      ->required();
  tolerance->add_option("--t0", t.grid.t0, "Start time")->required();
  tolerance->add_option("--t1", t.grid.t1, "End time")->required();
  tolerance->add_option("--steps", t.grid.steps, "Number of steps N (N + 1 rows)")->required();
  tolerance
      ->add_option("--monte-carlo", t.monte_carlo,
                   "Also N >= 2 analyses with parameters drawn uniformly in [p - DELTA, "
                   "p + DELTA]")
      ->check(CLI::Range(2, std::numeric_limits<int>::max()));
  tolerance->add_option("--seed", o->seed,
                        "Monte Carlo seed, 0 to 18446744073709551615 (default 1)");
  tolerance->add_option("-o,--output", o->output, "CSV file of the per-row figures");
  return {tolerance, [&common, o] { return run_tolerance(common, *o); }};
}

}  // namespace kinegen::cli
