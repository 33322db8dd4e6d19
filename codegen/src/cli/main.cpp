// kinegen: generate | analyze | eval | check. Exit status: 0 success, 1 the analysis (or a
// check) failed, 2 invalid input or usage. Every error is one `error:` line on stderr.
// This file: every subcommand's options (animate and tolerance too), the dispatch, the errors,
// and the helpers the subcommands share (cli.hpp); each subcommand's run_* is its own file.
#include <CLI/CLI.hpp>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>

#include "cli.hpp"
#include "kinegen/codegen/analysis/compiled_model.hpp"
#include "kinegen/codegen/base/log.hpp"
#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

std::vector<kc::ParamOverride> parse_overrides(const std::vector<std::string>& args) {
  std::vector<kc::ParamOverride> overrides;
  for (const auto& a : args) {
    const auto eq = a.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == a.size())
      throw kc::UsageError("--param expects NAME=VALUE, got '" + a + "'");
    overrides.push_back({a.substr(0, eq), a.substr(eq + 1)});
  }
  return overrides;
}

// Messages quote user text, which may hold line breaks; an error stays one line.
std::string one_line(std::string text) {
  for (char& ch : text)
    if (ch == '\n' || ch == '\r' || ch == '\t') ch = ' ';
  return text;
}

// Every time t0 + k (t1 - t0) / N must be a number: finite ends and a finite span.
void check_grid(double t0, double t1, int steps) {
  if (steps < 0) throw kc::UsageError("--steps must be 0 or more");
  if (!std::isfinite(t0) || !std::isfinite(t1))
    throw kc::UsageError("--t0 and --t1 must be finite");
  if (!std::isfinite(t1 - t0))
    throw kc::UsageError("--t1 - --t0 overflows (" + kc::format_number(t1) + " - " +
                         kc::format_number(t0) +
                         "); the times must be within about 1e308 of "
                         "each other");
}

// Reads and compiles the mechanism, its stages shown as the log's progress lines.
// Commands that run a motion (analyze, animate, tolerance) need every input driver as an
// --input table; generate keeps them (its code reads them from Params), and eval and check
// take them as 0, as a default Params does.
std::unique_ptr<kc::CompiledModel> load(const Common& c, kc::BuildOptions build,
                                        bool inputs_required) {
  build.progress = kc::Log::global().progress_callbacks();
  build.inputs_required = inputs_required;
  for (const std::string& in : c.inputs) {
    const auto eq = in.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == in.size())
      throw kc::UsageError("--input expects NAME=FILE.csv, not '" + in + "'");
    build.inputs.emplace_back(in.substr(0, eq), in.substr(eq + 1));
  }
  auto model = kc::CompiledModel::from_file(c.file, parse_overrides(c.params), build);
  for (const auto& w : model->symbolic().warnings) kc::Log::global().warning(w);
  return model;
}

void add_common(CLI::App* cmd, Common& c) {
  cmd->add_option("mechanism", c.file, "Mechanism file (YAML)")->required();
  cmd->add_option("--param", c.params, "Override a parameter: NAME=VALUE (repeatable)")
      ->type_name("NAME=VALUE");
  cmd->add_option("--input", c.inputs,
                  "An input driver's values (f: input): NAME=FILE.csv, columns t,value, "
                  "interpolated as a table (repeatable)")
      ->type_name("NAME=FILE");
}

// A progress bar on a terminal (stderr), for long runs.
std::function<void(int, int)> terminal_progress(const std::string& what) {
  if (!kc::Log::global().progress() || ::isatty(STDERR_FILENO) != 1) return {};
  return [what](int done, int total) {
    constexpr int kWidth = 40;
    const int filled = static_cast<int>(static_cast<long long>(kWidth) * done / total);
    std::fprintf(stderr, "\r\033[Kkinegen: %s [%s%s] %d/%d", what.c_str(),
                 std::string(filled, '#').c_str(), std::string(kWidth - filled, ' ').c_str(), done,
                 total);
    if (done == total) std::fputs("\r\033[K", stderr);
    std::fflush(stderr);
  };
}

}  // namespace kinegen::cli

int main(int argc, char** argv) {
  using namespace kinegen::cli;
  CLI::App app{"kinegen: planar kinematics, from a mechanism file to generated C++"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("kinegen ") + kc::kVersion);

  bool quiet = false, verbose = false;
  auto* quiet_flag =
      app.add_flag("-q,--quiet", quiet, "Errors only: no warnings, progress or 'wrote' lines");
  app.add_flag("-v,--verbose", verbose, "Every stage with its time and size")->excludes(quiet_flag);
  app.fallthrough();  // the flags may also follow the subcommand

  Common common;
  std::string out_dir = ".";
  bool fold_params = false;
  auto* generate = app.add_subcommand("generate", "Write <DIR>/<name>.hpp for a mechanism");
  add_common(generate, common);
  generate->add_option("-o,--output", out_dir, "Output directory (default: .)");
  generate->add_flag("--fold-params", fold_params,
                     "Fold the parameter values (with --param overrides) into constants");
  std::string name_space = "kinegen::models";
  generate->add_option("--namespace", name_space,
                       "C++ namespace of the model's struct (default kinegen::models); two models "
                       "of the same name need different ones to share a program");
  std::string outputs = "acceleration";
  generate
      ->add_option("--outputs", outputs,
                   "Analyses the header supports: position (phi, phi_q), velocity (adds nu) or "
                   "acceleration (adds gamma; default)")
      ->check(CLI::IsMember({"position", "velocity", "acceleration"}));
  int max_function_ops = kc::kDefaultMaxFunctionOps;
  generate
      ->add_option("--max-function-ops", max_function_ops,
                   "Split generated functions with more operations than this (or more outputs "
                   "than a fifth of it) into parts, for compile time (default " +
                       std::to_string(kc::kDefaultMaxFunctionOps) + "; 0: never split)")
      ->check(CLI::NonNegativeNumber);
  int roll_min = kc::kDefaultRollMin;
  generate
      ->add_option("--roll-min", roll_min,
                   "Emit Newton blocks that are alike up to their coordinates (the loops of a "
                   "chain) once, called with a table of coordinates, when at least this many are "
                   "alike (default " +
                       std::to_string(kc::kDefaultRollMin) + "; 0: never)")
      ->check(CLI::NonNegativeNumber);

  double t0 = 0, t1 = 0;
  int steps = 0;
  std::string csv;
  auto* analyze = app.add_subcommand("analyze", "Position, velocity and acceleration over time");
  add_common(analyze, common);
  analyze->add_option("--t0", t0, "Start time")->required();
  analyze->add_option("--t1", t1, "End time")->required();
  analyze->add_option("--steps", steps, "Number of steps N (N + 1 rows)")->required();
  analyze->add_option("-o,--output", csv, "CSV file (default: standard output)");
  int reference_digits = 0;
  analyze->add_option("--reference-digits", reference_digits,
                      "Solve in CLN arithmetic with N decimal digits (20 to 1000) instead of "
                      "double: the high-precision reference");
  bool strict = false;
  analyze->add_flag("--strict", strict,
                    "Redundant constraints are an error (exit 2), not a warning");
  std::string sensitivity_list;
  analyze
      ->add_option("--sensitivity", sensitivity_list,
                   "Add d(C)/d(p) columns for these parameters (comma-separated), after all "
                   "others")
      ->type_name("P1,P2,...");
  std::string solver = "block";
  analyze
      ->add_option("--solver", solver,
                   "block (default): block by block, as generated code solves, with the same "
                   "numbers; dense: Newton on all of Phi_q (sparse LU above 48 coordinates), "
                   "an independent cross-check. Redundant models always take the dense path")
      ->check(CLI::IsMember({"block", "dense"}));
  bool with_forces = false;
  analyze->add_flag("--forces", with_forces,
                    "Add the drivers' efforts and the joints' reactions (masses, gravity and "
                    "forces in the file): D.effort, J.fx, J.fy, J.tz columns");

  double t = 0;
  std::vector<double> q_arg, qd_arg;
  auto* eval = app.add_subcommand("eval", "Print Phi, Phi_q, nu and gamma as JSON");
  add_common(eval, common);
  eval->add_option("--t", t, "Time (default 0)");
  eval->add_option("--q", q_arg, "Coordinates (default: q0)")
      ->delimiter(',')
      ->allow_extra_args(false);
  eval->add_option("--qd", qd_arg, "Velocities (default: zeros)")
      ->delimiter(',')
      ->allow_extra_args(false);

  kc::CheckOptions check_options;
  bool structure = false;
  auto* check = app.add_subcommand("check", "Compare Phi_q, nu and gamma with numeric derivatives");
  add_common(check, common);
  check->add_option("--samples", check_options.samples, "Random configurations (default 5)");
  check->add_option("--seed", check_options.seed, "Random seed (default 1)");
  check->add_option("--t", check_options.t, "Time around which to sample (default 0)");
  check->add_flag("--structure", structure, "Also print the structure of Phi_q");
  check->add_option("--turns", check_options.turns,
                    "Shift every angle by 2 pi K: check after many revolutions (default 0)");
  check->add_option("--digits", check_options.digits,
                    "Decimal digits of the CLN method (default 40)");

  kc::AnimateOptions animate_options;
  std::string svg_file;
  auto* animate = app.add_subcommand("animate", "Draw the mechanism moving over an analysis (SVG)");
  add_common(animate, common);
  animate->add_option("--t0", animate_options.grid.t0, "Start time")->required();
  animate->add_option("--t1", animate_options.grid.t1, "End time")->required();
  animate->add_option("--steps", animate_options.grid.steps, "Number of steps N (N + 1 frames)")
      ->required();
  animate->add_option("-o,--output", svg_file, "SVG file")->required();
  animate->add_option("--frame", animate_options.frame, "Draw only frame K (0..N), not animated");
  animate->add_option("--width", animate_options.width, "Width in pixels (default 800)");
  animate->add_flag("--forces", animate_options.forces,
                    "Draw each joint's reaction force as an arrow (needs masses or loads)");
  animate->add_option("--duration", animate_options.duration,
                      "Seconds per pass (default: t1 - t0)");

  kc::ToleranceOptions tol_options;
  std::vector<std::string> tol_items;
  std::string tol_csv;
  auto* tolerance = app.add_subcommand(
      "tolerance", "Worst-case and RSS deviations of the positions from parameter tolerances");
  add_common(tolerance, common);
  tolerance->add_option("--tol", tol_items, "A parameter's tolerance: NAME=DELTA (repeatable)")
      ->type_name("NAME=DELTA")
      ->required();
  tolerance->add_option("--t0", tol_options.grid.t0, "Start time")->required();
  tolerance->add_option("--t1", tol_options.grid.t1, "End time")->required();
  tolerance->add_option("--steps", tol_options.grid.steps, "Number of steps N (N + 1 rows)")
      ->required();
  tolerance
      ->add_option("--monte-carlo", tol_options.monte_carlo,
                   "Also N >= 2 analyses with parameters drawn uniformly in [p - DELTA, "
                   "p + DELTA]")
      ->check(CLI::Range(2, std::numeric_limits<int>::max()));
  tolerance->add_option("--seed", tol_options.seed, "Monte Carlo seed (default 1)");
  tolerance->add_option("-o,--output", tol_csv, "CSV file of the per-row figures");

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "error: " << e.what() << " (see kinegen --help)\n";
    return kExitInvalid;
  }

  kc::Log::global().set_verbosity(quiet     ? kc::Verbosity::kQuiet
                                  : verbose ? kc::Verbosity::kVerbose
                                            : kc::Verbosity::kNormal);
  try {
    if (*generate)
      return run_generate(common, out_dir, outputs, fold_params, max_function_ops, roll_min,
                          name_space);
    if (*animate) return run_animate(common, animate_options, svg_file);
    if (*analyze) return run_analyze(common, t0, t1, steps, csv, reference_digits, strict,
                                       sensitivity_list, with_forces, solver);
    if (*eval) return run_eval(common, t, q_arg, qd_arg);
    if (*tolerance) return run_tolerance(common, tol_options, tol_items, tol_csv);
    if (*check) return run_check(common, check_options, structure);
  } catch (const kc::InputError& e) {
    std::cerr << "error: " << one_line(e.what()) << "\n";
    return kExitInvalid;
  } catch (const kc::UsageError& e) {
    // Usage problems found after reading the file (--q length, --param form) name it too.
    std::cerr << "error: " << one_line(common.file + ": " + e.what()) << "\n";
    return kExitInvalid;
  } catch (const kc::AnalysisError& e) {
    std::cerr << "error: " << one_line(e.what()) << "\n";
    return kExitFailed;
  } catch (const kc::OutputError& e) {
    std::cerr << "error: " << one_line(e.what()) << "\n";
    return kExitFailed;
  } catch (const std::exception& e) {
    std::cerr << "error: " << one_line(common.file + ": internal error: " + e.what()) << "\n";
    return kExitFailed;
  }
  return 0;
}
