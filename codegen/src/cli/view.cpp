// `kinegen view`: one self-contained HTML page of a run (a CSV, or an analysis run here) or of
// vibration modes, with the mechanism drawn as animate draws it, a time slider and plots.
#include "kinegen/codegen/io/view.hpp"

#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "cli.hpp"
#include "kinegen/codegen/base/log.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

namespace {

struct ViewArgs {
  std::string csv, modes, output;
  std::optional<double> t0, t1;
  std::optional<int> steps;
  bool forces = false;
  int max_rows = 200000;
  int width = 800;
};

int run_view(const Common& c, const ViewArgs& o) {
  const bool grid = o.t0 || o.t1 || o.steps;
  if (static_cast<int>(!o.csv.empty()) + static_cast<int>(!o.modes.empty()) + grid != 1)
    throw kc::UsageError(
        "view shows one of: --csv RUN.csv, --modes MODES.json, or an analysis "
        "(--t0, --t1, --steps)");
  if (grid && !(o.t0 && o.t1 && o.steps))
    throw kc::UsageError("an analysis to view needs --t0, --t1 and --steps");
  if (o.forces && !grid) throw kc::UsageError("--forces belongs to an analysis (--t0 ...)");
  if (o.max_rows < 2) throw kc::UsageError("--max-rows must be at least 2");
  kc::require_viewer();  // before any work
  // A run read from a file (a simulation's CSV, a modes JSON) has the free coordinates' values
  // in it: they are state, not inputs needing tables as in an analysis.
  kc::BuildOptions build;
  build.free_as_state = !grid;
  const auto model = load(c, build);
  if (model->mechanism().spatial && (!o.modes.empty() || o.forces))
    throw kc::InputError(c.file, "space", model->mechanism().space_loc,
                         std::string("spatial files (space: 3d) are not supported by `kinegen "
                                     "view ") +
                             (o.forces ? "--forces" : "--modes") + "` yet");
  kc::ViewOptions options;
  options.width = o.width;
  std::string html;
  {
    kc::StageScope stage(grid ? "analysis and page" : "page");
    if (!o.modes.empty()) {
      html = kc::view_modes_html(*model, kc::read_modes_json(o.modes, *model), options);
    } else {
      kc::RunTable run;
      if (grid) {
        check_grid(*o.t0, *o.t1, *o.steps);
        run = kc::analysis_table(*model, {*o.t0, *o.t1, *o.steps}, o.forces,
                                 static_cast<std::size_t>(o.max_rows), warning_sink(),
                                 &options.failure);
      } else {
        run = kc::read_run_csv(o.csv, static_cast<std::size_t>(o.max_rows));
      }
      if (run.stride > 1)
        kc::Log::global().warning(run.source + ": " + std::to_string(run.total_rows) +
                                  " rows; the page keeps one in " + std::to_string(run.stride) +
                                  " and the last, " + std::to_string(run.rows()) + " (--max-rows " +
                                  std::to_string(o.max_rows) + ")");
      html = kc::view_html(*model, run, options);
    }
    stage.done(std::to_string(html.size() / 1024) + " KiB of HTML");
  }
  kc::OutputFile out(o.output);
  out.stream() << html;
  out.commit();
  kc::Log::global().info("wrote " + o.output);
  if (!options.failure.empty()) {
    std::cerr << "error: " << one_line(options.failure) << "\n";
    return kExitFailed;  // the page shows the rows solved so far
  }
  return 0;
}

}  // namespace

Subcommand add_view(CLI::App& app, Common& common) {
  const auto o = std::make_shared<ViewArgs>();
  auto* view = app.add_subcommand(
      "view", "One self-contained HTML page: the mechanism moving over a run, with plots");
  add_common(view, common);
  view->add_option("--csv", o->csv,
                   "A run to show: the CSV of analyze (or any with its "
                   "position columns)");
  view->add_option("--modes", o->modes,
                   "Vibration modes to play: JSON {q, frequencies, shapes} (dq per coordinate)");
  view->add_option("--t0", o->t0, "Or analyze here: start time");
  view->add_option("--t1", o->t1, "End time");
  view->add_option("--steps", o->steps, "Number of steps N (N + 1 rows)");
  view->add_flag("--forces", o->forces,
                 "With an analysis: add the force columns, drawn as arrows (as analyze --forces)");
  view->add_option("-o,--output", o->output, "HTML file")->required();
  view->add_option("--max-rows", o->max_rows,
                   "Rows the page keeps (default 200000); of more, every k-th and the last");
  view->add_option("--width", o->width, "Width of the drawing in pixels (default 800)");
  return {view, [&common, o] { return run_view(common, *o); }};
}

}  // namespace kinegen::cli
