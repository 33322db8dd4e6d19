// `kinegen animate`: an SVG of the mechanism moving over an analysis (or one frame of it).
#include "kinegen/codegen/io/animate.hpp"

#include <cmath>
#include <iostream>
#include <string>

#include "cli.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/base/log.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

int run_animate(const Common& c, kc::AnimateOptions options, const std::string& output) {
  check_grid(options.grid.t0, options.grid.t1, options.grid.steps);
  options.warn = [](const std::string& w) { std::cerr << "warning: " << one_line(w) << "\n"; };
  if (!std::isfinite(options.duration) || options.duration < 0)
    throw kc::UsageError("--duration must be a finite number of seconds (0: t1 - t0)");
  const auto model = load(c);
  kc::require_driven(*model);
  std::string svg;
  {
    kc::StageScope stage("analysis and drawing");
    svg = kc::animate_svg(*model, options);
    stage.done(std::to_string(svg.size() / 1024) + " KiB of SVG");
  }
  kc::OutputFile out(output);
  out.stream() << svg;
  out.commit();
  kc::Log::global().info("wrote " + output);
  return 0;
}

}  // namespace kinegen::cli
