// Tolerance analysis (`kinegen tolerance`): how parameter tolerances move the solved positions
// over a motion. From the exact sensitivities (sensitivity.hpp), per row and quantity, the
// linear worst case sum_p |dC/dp| delta_p and the root-sum-square sqrt(sum_p (dC/dp
// delta_p)^2); optionally a Monte Carlo check: N full analyses with each parameter drawn
// uniformly from [p - delta, p + delta]. For small tolerances the worst case bounds the sampled
// spread, and the sampled standard deviation tends to RSS / sqrt(3) (the standard deviation of
// a uniform draw is delta / sqrt(3)).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"

namespace kinegen::codegen {

struct Tolerance {
  std::string name;
  double delta = 0;  // >= 0 and finite
};

// Parses NAME=DELTA items; a malformed item, a negative or non-finite DELTA and a repeated name
// are UsageErrors (exit 2).
std::vector<Tolerance> parse_tolerances(const std::vector<std::string>& items);

struct ToleranceOptions {
  std::vector<Tolerance> tolerances;
  TimeGrid grid;
  int monte_carlo = 0;  // samples; 0: none, else at least 2
  std::uint64_t seed = 1;
  // The --param overrides the model was built with: each Monte Carlo sample is rebuilt from
  // the file's mechanism with these and then its drawn values.
  std::vector<ParamOverride> overrides;
  // Called after each Monte Carlo sample (done, total).
  std::function<void(int, int)> progress;
  // Receives the nominal analysis' warnings (AnalysisOptions::warn); the samples' are not
  // repeated.
  std::function<void(const std::string&)> warn;
};

// The quantities are every body's x, y, phi, every extra coordinate and every point's x, y,
// in CSV order.
struct ToleranceResult {
  std::vector<std::string> quantities;
  std::vector<double> t;                        // rows
  std::vector<std::vector<double>> worst, rss;  // [row][quantity]
  // With Monte Carlo: the largest |C_sample - C_nominal| and the samples' standard deviation.
  std::vector<std::vector<double>> mc_spread, mc_std;
  int samples = 0;
};

// Throws UsageError (unknown parameter, N = 1 or negative, no --tol) and AnalysisError (the
// nominal analysis or a sample fails, naming the sample's values).
ToleranceResult tolerance_analysis(const CompiledModel& model, const ToleranceOptions& options);

// The summary printed on standard output: per quantity the largest worst case and RSS over the
// motion and the t where each is largest (and the Monte Carlo figures next to them).
std::string tolerance_summary(const ToleranceResult& result, const ToleranceOptions& options);
// Per-row figures: t, then for each quantity Q `Q.worst, Q.rss` (and `Q.mc_spread, Q.mc_std`).
std::string tolerance_csv(const ToleranceResult& result);

}  // namespace kinegen::codegen
