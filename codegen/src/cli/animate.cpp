// `kinegen animate`: an SVG of the mechanism moving over an analysis (or one frame of it).
#include "kinegen/codegen/io/animate.hpp"

#include <cmath>
#include <iostream>
#include <memory>
#include <string>

#include "cli.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/base/log.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

namespace {

struct Options {
  kc::AnimateOptions animate;
  std::string output;
};

int run_animate(const Common& c, const Options& o) {
  kc::AnimateOptions options = o.animate;
  check_grid(options.grid.t0, options.grid.t1, options.grid.steps);
  options.warn = warning_sink();
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
  kc::OutputFile out(o.output);
  out.stream() << svg;
  out.commit();
  kc::Log::global().info("wrote " + o.output);
  return 0;
}

}  // namespace

Subcommand add_animate(CLI::App& app, Common& common) {
  const auto o = std::make_shared<Options>();
  kc::AnimateOptions& a = o->animate;
  auto* animate = app.add_subcommand("animate", "Draw the mechanism moving over an analysis (SVG)");
  add_common(animate, common);
  animate->add_option("--t0", a.grid.t0, "Start time")->required();
  animate->add_option("--t1", a.grid.t1, "End time")->required();
  animate->add_option("--steps", a.grid.steps, "Number of steps N (N + 1 frames)")->required();
  animate->add_option("-o,--output", o->output, "SVG file")->required();
  animate->add_option("--frame", a.frame, "Draw only frame K (0..N), not animated");
  animate->add_option("--width", a.width, "Width in pixels (default 800)");
  animate->add_flag("--forces", a.forces,
                    "Draw each joint's reaction force as an arrow (needs masses or loads)");
  animate->add_option("--duration", a.duration, "Seconds per pass (default: t1 - t0)");
  return {animate, [&common, o] { return run_animate(common, *o); }};
}

}  // namespace kinegen::cli
