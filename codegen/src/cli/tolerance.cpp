// `kinegen tolerance`: worst-case and RSS deviations of the positions from parameter
// tolerances, optionally with a Monte Carlo check.
#include "kinegen/codegen/analysis/tolerance.hpp"

#include <string>
#include <vector>

#include "cli.hpp"
#include "kinegen/codegen/base/log.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

int run_tolerance(const Common& c, kc::ToleranceOptions options,
                  const std::vector<std::string>& tol, const std::string& output) {
  options.overrides = parse_overrides(c.params);
  auto model = load(c);
  kc::require_driven(*model);
  options.tolerances = kc::parse_tolerances(tol);
  {
    // A derived parameter with a tolerance varies on its own (spec 6.6).
    std::vector<std::string> names;
    for (const auto& t : options.tolerances) names.push_back(t.name);
    if (auto base = model->with_base_parameters(names)) model = std::move(base);
  }
  options.progress = terminal_progress("Monte Carlo");
  const auto result = kc::tolerance_analysis(*model, options);
  kc::OutputFile summary("-");
  summary.stream() << kc::tolerance_summary(result, options);
  summary.commit();
  if (!output.empty()) {
    kc::OutputFile out(output);
    out.stream() << kc::tolerance_csv(result);
    out.commit();
  }
  return 0;
}

}  // namespace kinegen::cli
