// The cost of sensitivities in the in-process analysis (`kinegen analyze --sensitivity`): ns
// per row for the full step (position, velocity, acceleration) without sensitivities, and the
// extra ns per row and parameter with all the example's parameters. Prints numbers; not a test.
// Run: build/bench/bench_sensitivity
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis.hpp"
#include "kinegen/codegen/model.hpp"
#include "kinegen/codegen/sensitivity.hpp"

namespace cg = kinegen::codegen;

namespace {

// Best of `repeats` runs of a 3600-row analysis (0.1 degree crank steps), in ns per row.
double ns_per_row(const cg::CompiledModel& model, const cg::SensitivityModel* sensitivity) {
  constexpr int kSteps = 3600;
  constexpr int kRepeats = 7;
  double best = 1e300;
  cg::AnalysisOptions options;
  options.sensitivity = sensitivity;
  double sink = 0;
  for (int r = 0; r < kRepeats; ++r) {
    const auto start = std::chrono::steady_clock::now();
    cg::run_analysis(
        model, {0, 2 * std::acos(-1.0), kSteps}, [&](const cg::StateRow& row) { sink += row.q[0]; },
        options);
    const double ns =
        std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count();
    best = std::min(best, ns / (kSteps + 1));
  }
  if (sink == 12345.678) std::puts("");  // keeps the work
  return best;
}

}  // namespace

int main() {
  std::printf("%-22s %6s %14s %16s %18s\n", "model", "params", "step ns/row", "with sens ns/row",
              "sens ns/row/param");
  for (const char* name : {"slider_crank", "offset_slider_crank", "four_bar", "quick_return"}) {
    const auto model = cg::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/examples/" +
                                                    name + ".yaml");
    std::vector<std::string> params;
    for (const auto& p : model->mechanism().parameters) params.push_back(p.name);
    const auto sens = cg::build_sensitivity(*model, params);
    const double plain = ns_per_row(*model, nullptr);
    const double with = ns_per_row(*model, &sens);
    std::printf("%-22s %6zu %14.0f %16.0f %18.0f\n", name, params.size(), plain, with,
                (with - plain) / params.size());
  }
}
