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
#include "linear.hpp"

namespace kinegen::cli {

namespace {

struct AnimateArgs {
  kc::AnimateOptions animate;
  std::string output;
  int mode = 0;  // 1-based; 0: an analysis
  double amplitude = 0.1;
  std::string at;
  bool grid_given = false;
};

int run_animate(const Common& c, const AnimateArgs& o) {
  if (o.mode != 0) return run_animate_mode(c, o.animate, o.output, o.mode, o.amplitude, o.at);
  if (!o.grid_given)
    throw kc::UsageError("animate needs --t0, --t1 and --steps (or --mode K for a vibration mode)");
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
  const auto o = std::make_shared<AnimateArgs>();
  kc::AnimateOptions& a = o->animate;
  auto* animate = app.add_subcommand("animate", "Draw the mechanism moving over an analysis (SVG)");
  add_common(animate, common);
  auto* t0 = animate->add_option("--t0", a.grid.t0, "Start time");
  auto* t1 = animate->add_option("--t1", a.grid.t1, "End time");
  auto* steps = animate->add_option("--steps", a.grid.steps, "Number of steps N (N + 1 frames)");
  animate->add_option("-o,--output", o->output, "SVG file")->required();
  animate->add_option("--frame", a.frame, "Draw only frame K (0..N), not animated");
  animate->add_option("--width", a.width, "Width in pixels (default 800)");
  animate->add_flag("--forces", a.forces,
                    "Draw each joint's reaction force as an arrow (needs masses or loads)");
  animate->add_option("--duration", a.duration, "Seconds per pass (default: t1 - t0)");
  animate->add_option("--mode", o->mode,
                      "Draw vibration mode K (1 the lowest; kinegen modes) as a small "
                      "oscillation about the equilibrium, one period per pass, instead of an "
                      "analysis");
  animate->add_option("--amplitude", o->amplitude,
                      "--mode's amplitude: the largest free coordinate's swing, in radians or "
                      "length scales (default 0.1)");
  animate->add_option("--at", o->at, "--mode about this point (as kinegen modes --at)");
  return {animate, [&common, o, t0, t1, steps] {
            o->grid_given = *t0 && *t1 && *steps;
            if (o->mode != 0 && (*t0 || *t1))
              throw kc::UsageError("--t0 and --t1 do not apply to --mode (one period is drawn)");
            if (!o->grid_given && o->mode == 0 && (*t0 || *t1 || *steps))
              throw kc::UsageError("animate needs all of --t0, --t1 and --steps");
            if (o->mode != 0 && !*steps) o->animate.grid.steps = 40;  // frames per period
            return run_animate(common, *o);
          }};
}

}  // namespace kinegen::cli
