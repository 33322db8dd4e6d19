// `kinegen simulate`: forward dynamics on SUNDIALS CVODE, rows on the --steps grid,
// with the free coordinates and the energy columns.
#include "kinegen/codegen/analysis/simulate.hpp"

#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "cli.hpp"
#include "kinegen/codegen/analysis/breakpoints.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/reference_dynamics.hpp"
#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/base/log.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

namespace {

struct SimulateArgs {
  double t0 = 0, t1 = 0;
  int steps = 0;
  double rtol = 1e-8;
  std::optional<double> atol;  // default: 1e-2 rtol
  double max_step = 0;
  bool allow_drift = false;
  std::string method = "minimal", integrator = "auto";
  std::string output;
  bool with_forces = false;
  int reference_digits = 0;
};

// The options checked (before the file is read), as the simulation takes them.
kc::SimulateOptions check_options(const SimulateArgs& o) {
  check_grid(o.t0, o.t1, o.steps);
  if (!(o.t1 > o.t0))
    throw kc::UsageError("--t1 (" + kc::format_number(o.t1) + ") must come after --t0 (" +
                         kc::format_number(o.t0) + "): a simulation runs forward in time");
  if (o.steps < 1) throw kc::UsageError("--steps must be at least 1");
  if (o.reference_digits != 0) kc::check_reference_digits(o.reference_digits);
  kc::SimulateOptions options = kc::simulate_options(o.rtol, o.atol, o.method, o.integrator, "--");
  if (!(o.max_step >= 0) || !std::isfinite(o.max_step))
    throw kc::UsageError("--max-step must be a finite number above 0, not " +
                         kc::format_number(o.max_step));
  options.max_step = o.max_step;
  options.allow_drift = o.allow_drift;
  return options;
}

// The progress bar, drawn only once a run has taken a second.
std::function<void(double)> progress_after_a_second(double t0, double t1) {
  auto bar = terminal_progress("simulating");
  if (!bar) return {};
  const auto start = std::chrono::steady_clock::now();
  return [bar, t0, t1, start](double t) {
    if (std::chrono::steady_clock::now() - start < std::chrono::seconds(1) && t < t1) return;
    bar(static_cast<int>(std::lround(1000 * (t - t0) / (t1 - t0))), 1000);
  };
}

// The line that says stop_when ended the run (CVODE's and the reference's alike); bound: 0, or
// the error bound at t0 that EXPR, within it above 0 there, rose past (StopWhenLevel).
void report_stop(const kc::Mechanism& m, double t, double bound) {
  std::cerr << "stopped at " << kc::format_time(t) << ": " << one_line(m.stop_when->text)
            << (bound > 0 ? " rose past its error bound at t0, " + kc::format_number(bound) +
                                " (it started within it, above 0)"
                          : std::string(" crossed 0"))
            << "\n";
}

// What the run did: the stop_when line, the drift warning, and with -v the integrator's
// figures.
void report(const kc::Mechanism& m, const kc::SimulateSummary& s) {
  kc::Log& log = kc::Log::global();
  if (s.stopped) report_stop(m, s.stop_time, s.stop_bound);
  if (s.drifted) log.warning(m.source + ": " + s.drift);
  log.detail("integrator " + s.integrator + ": " + std::to_string(s.steps) + " steps, " +
             std::to_string(s.evaluations) + " evaluations, " +
             std::to_string(s.error_test_failures) + " error-test failures, " +
             std::to_string(s.restarts) + " restarts at breakpoints");
  log.detail("largest |energy.balance| " + kc::format_estimate(s.largest_balance) + " at " +
             kc::format_time(s.largest_balance_time) + " (" + kc::format_estimate(s.largest_ratio) +
             " of its tolerance term C (rtol + atol/S) (S + X))");
}

int run_simulate(const Common& c, const SimulateArgs& o) {
  kc::SimulateOptions options = check_options(o);
  kc::BuildOptions build;
  build.free_as_state = true;
  auto model = load(c, build);
  kc::check_input_coverage(*model, o.t0, o.t1);  // before the output file is opened
  if (o.reference_digits != 0) kc::check_reference_stop_when(*model);
  const kc::ForceModel forces = kc::derive_forces(*model);
  std::vector<std::string> force_names;
  if (o.with_forces) {
    options.forces_columns = &forces;
    force_names = kc::force_columns(model->mechanism());
  }
  options.progress = progress_after_a_second(o.t0, o.t1);
  const int nb = static_cast<int>(model->mechanism().bodies.size());
  // The checks at t0 (docs/format.md: `free`) come first, so that bad input writes no file.
  kc::OutputFile file(o.output.empty() ? "-" : o.output);
  std::ostream& out = file.stream();
  int status = 0, rows = 0;
  double t_last = 0;
  bool header = false;
  const auto sink = [&](const kc::SimulatedRow& row) {
    if (!header) out << kc::simulate_csv_header(model->mechanism(), force_names);
    header = true;
    out << kc::simulate_csv_row(row, nb);
    file.check();
    ++rows;
    t_last = row.state.t;
  };
  try {
    if (o.reference_digits != 0) {
      const auto stats = kc::run_reference_simulation(*model, forces, {o.t0, o.t1, o.steps},
                                                      o.reference_digits, sink, options);
      if (stats.stopped) report_stop(model->mechanism(), stats.stop_time, stats.stop_bound);
    } else {
      const kc::SimulateSummary s =
          kc::run_simulation(*model, forces, {o.t0, o.t1, o.steps}, sink, options);
      report(model->mechanism(), s);
    }
  } catch (const kc::AnalysisError& e) {
    std::cerr << "error: " << one_line(e.what()) << "\n";
    status = kExitFailed;  // the rows so far are kept
  } catch (const kc::Interrupted&) {
    status = interrupted(c.file, rows, t_last);  // as a failure: the rows so far are kept
  }
  if (rows > 0 || status == 0 || !file.replaces_target()) file.commit();
  return status;
}

}  // namespace

Subcommand add_simulate(CLI::App& app, Common& common) {
  const auto o = std::make_shared<SimulateArgs>();
  auto* cmd = app.add_subcommand("simulate", "Forward dynamics: the motion under the forces");
  add_common(cmd, common);
  cmd->add_option("--t0", o->t0, "Start time (default 0)");
  cmd->add_option("--t1", o->t1, "End time")->required();
  cmd->add_option("--steps", o->steps, "Rows on the grid: N steps (N + 1 rows)")->required();
  cmd->add_option("--rtol", o->rtol, "Relative tolerance of the integrator (default 1e-8)");
  cmd->add_option("--atol", o->atol,
                  "Absolute tolerance, times each state's scale (default 1e-2 times --rtol); "
                  "usable: 1e-18 to 1e-2 (--rtol: 1e-14 to 1e-2)");
  cmd->add_option("--max-step", o->max_step,
                  "The integrator's largest internal step (default: none; stop_when limits it "
                  "near crossings)")
      ->type_name("H");
  cmd->add_flag("--allow-drift", o->allow_drift,
                "An energy balance past its bound (the run's accuracy witness) is a warning with "
                "the largest value and its time, not a failure");
  cmd->add_option("--method", o->method,
                  "minimal (default): minimal coordinates, the free items as the state; "
                  "augmented: an augmented Lagrangian in all coordinates, which passes "
                  "singular positions")
      ->check(CLI::IsMember({"minimal", "augmented"}));
  cmd->add_option("--integrator", o->integrator,
                  "CVODE's method: auto (default: BDF with springs or dampers, else Adams), "
                  "bdf or adams")
      ->check(CLI::IsMember({"auto", "bdf", "adams"}));
  cmd->add_option("-o,--output", o->output, "CSV file (default: standard output)");
  cmd->add_flag("--forces", o->with_forces,
                "Add the prescribed drivers' efforts and the joints' reactions along the motion");
  cmd->add_option("--reference", o->reference_digits,
                  "Integrate with D significant digits in CLN arithmetic (Gragg-Bulirsch-Stoer "
                  "extrapolation; about D - 5 correct digits; for tests); --rtol, --atol, "
                  "--integrator do not apply")
      ->type_name("D");
  return {cmd, [&common, o] { return run_simulate(common, *o); }};
}

}  // namespace kinegen::cli
