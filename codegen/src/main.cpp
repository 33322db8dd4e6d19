// kinegen: generate | analyze | eval | check. Exit status: 0 success, 1 the analysis (or a
// check) failed, 2 invalid input or usage. Every error is one `error:` line on stderr.
#include <CLI/CLI.hpp>
#include <unistd.h>

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <kinegen/solver.hpp>
#include <limits>
#include <sstream>

#include "kinegen/codegen/analysis.hpp"
#include "kinegen/codegen/animate.hpp"
#include "kinegen/codegen/check.hpp"
#include "kinegen/codegen/emit_cpp.hpp"
#include "kinegen/codegen/forces.hpp"
#include "kinegen/codegen/log.hpp"
#include "kinegen/codegen/model.hpp"
#include "kinegen/codegen/output_file.hpp"
#include "kinegen/codegen/reference.hpp"
#include "kinegen/codegen/reserved_names.hpp"
#include "kinegen/codegen/sensitivity.hpp"
#include "kinegen/codegen/tolerance.hpp"

namespace kc = kinegen::codegen;
namespace fs = std::filesystem;

namespace {

constexpr int kExitFailed = 1;
constexpr int kExitInvalid = 2;

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

// `check --turns K` and `--t`: beyond this the inputs' own rounding (eps * 2 pi K rad) makes the
// derivative bounds grow to meaninglessness; at 1e7 turns an angle is known to 1.4e-8 rad and
// the central-difference bound is 6e-4 (docs/stability.md).
constexpr double kMaxCheckTurns = 1e7;

std::string json_number(double v) { return std::isfinite(v) ? kc::format_number(v) : "null"; }

std::string json_array(const Eigen::VectorXd& v) {
  std::string s = "[";
  for (int k = 0; k < v.size(); ++k) s += (k ? ", " : "") + json_number(v[k]);
  return s + "]";
}

Eigen::VectorXd vector_arg(const std::vector<double>& values, int n, const char* option) {
  if (static_cast<int>(values.size()) != n)
    throw kc::UsageError(std::string(option) + " expects " + std::to_string(n) +
                         " comma-separated values (one per coordinate), got " +
                         std::to_string(values.size()));
  return Eigen::Map<const Eigen::VectorXd>(values.data(), n);
}

struct Common {
  std::string file;
  std::vector<std::string> params;
  std::vector<std::string> inputs;  // NAME=FILE.csv
};

// Reads and compiles the mechanism, its stages shown as the log's progress lines.
// Commands that run a motion (analyze, animate, tolerance) need every input driver as an
// --input table; generate keeps them (its code reads them from Params), and eval and check
// take them as 0, as a default Params does.
std::unique_ptr<kc::CompiledModel> load(const Common& c, kc::BuildOptions build = {},
                                        bool inputs_required = true) {
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

int run_generate(const Common& c, const std::string& dir, const std::string& outputs,
                 bool fold_params, int max_function_ops, int roll_min,
                 const std::string& name_space) {
  // A bad --namespace is a usage error before any work.
  if (const auto why = kc::namespace_conflict(name_space); !why.empty())
    throw kc::UsageError("--namespace: " + why);
  kc::BuildOptions build;
  build.fold_params = fold_params;
  const auto model = load(c, build, false);
  kc::StageScope stage("emitting C++");
  kc::EmitOptions options;
  if (outputs == "position") options.outputs = kc::Outputs::kPosition;
  if (outputs == "velocity") options.outputs = kc::Outputs::kVelocity;
  options.folded_params = fold_params;
  options.max_function_ops = max_function_ops;
  options.roll_min = roll_min;
  options.name_space = name_space;
  const std::string text = kc::emit_header(model->mechanism(), model->symbols(), model->symbolic(),
                                           model->programs(), options);
  stage.done(std::to_string(text.size() / 1024) + " KiB");
  std::error_code ec;
  fs::create_directories(dir, ec);
  const fs::path target = fs::path(dir) / (model->mechanism().name + ".hpp");
  kc::OutputFile out(target.string());
  out.stream() << text;
  out.commit();
  kc::Log::global().info("wrote " + target.string() + " (nq = " + std::to_string(model->nq()) +
                         ", nc = " + std::to_string(model->nc()) + ", " +
                         std::to_string(model->programs().jac_rows.size()) +
                         " Jacobian non-zeros)");
  return 0;
}

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

int run_analyze(const Common& c, double t0, double t1, int steps, const std::string& output,
                int reference_digits, bool strict, const std::string& sensitivity_list,
                bool with_forces, const std::string& solver) {
  auto model = load(c);
  kc::require_driven(*model);
  check_grid(t0, t1, steps);
  if (reference_digits != 0 &&
      (reference_digits < kc::kMinReferenceDigits || reference_digits > kc::kMaxReferenceDigits))
    throw kc::UsageError("--reference-digits must be between " +
                         std::to_string(kc::kMinReferenceDigits) + " and " +
                         std::to_string(kc::kMaxReferenceDigits));
  kc::SensitivityModel sensitivity;
  if (!sensitivity_list.empty()) {
    if (reference_digits != 0)
      throw kc::UsageError("--sensitivity is not available with --reference-digits");
    const auto names = kc::split_parameter_list(sensitivity_list);
    // Naming a derived parameter treats it as overridden (spec 6.6).
    if (auto base = model->with_base_parameters(names)) model = std::move(base);
    sensitivity = kc::build_sensitivity(*model, names);
  }
  // Forces: every input error (masses, loads) before any output.
  std::unique_ptr<kc::ForceModel> forces;
  std::vector<std::string> force_names;
  if (with_forces) {
    forces = std::make_unique<kc::ForceModel>(kc::forces_for_analysis(*model, t0));
    force_names = kc::force_columns(model->mechanism());
  }
  kc::OutputFile file(output.empty() ? "-" : output);
  std::ostream& out = file.stream();
  out << kc::csv_header(model->mechanism(), force_names, sensitivity.names);
  int status = 0;
  int rows = 0;
  try {
    const auto sink = [&](const kc::StateRow& row) {
      out << kc::csv_row(row, static_cast<int>(model->mechanism().bodies.size()));
      file.check();  // a full disk or a closed pipe ends the run now, not after it
      ++rows;
    };
    if (reference_digits != 0 && forces) {
      // The forces of the reference come from its own high-precision rows.
      kc::ReferenceForces reference(*model, *forces, reference_digits);
      kc::run_reference_analysis_exact(
          *model, {t0, t1, steps}, reference_digits, [&](const kc::ReferenceRow& exact) {
            kc::StateRow row = kc::to_state_row(exact);
            for (const auto& v : reference.solve(exact)) row.forces.push_back(v.to_double());
            sink(row);
          });
    } else if (reference_digits != 0) {
      kc::run_reference_analysis(*model, {t0, t1, steps}, reference_digits, sink);
    } else {
      kc::AnalysisOptions options;
      options.strict = strict;
      options.block_solver = solver != "dense";
      if (!sensitivity_list.empty()) options.sensitivity = &sensitivity;
      options.forces = forces.get();
      options.warn = [](const std::string& w) { std::cerr << "warning: " << one_line(w) << "\n"; };
      kc::run_analysis(*model, {t0, t1, steps}, sink, options);
    }
  } catch (const kc::AnalysisError& e) {
    std::cerr << "error: " << one_line(e.what()) << "\n";
    status = kExitFailed;  // the rows solved so far are kept
  }
  // Nothing solved: a file is left as it was; standard output gets the header, as before.
  if (rows > 0 || status == 0 || !file.replaces_target()) file.commit();
  return status;
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

int run_eval(const Common& c, double t, const std::vector<double>& q_arg,
             const std::vector<double>& qd_arg) {
  const auto model = load(c, {}, false);
  const int nq = model->nq(), nc = model->nc();
  const Eigen::VectorXd q = q_arg.empty() ? model->q0() : vector_arg(q_arg, nq, "--q");
  const Eigen::VectorXd qd =
      qd_arg.empty() ? Eigen::VectorXd::Zero(nq) : vector_arg(qd_arg, nq, "--qd");
  kc::ModelEvaluator<double> eval(*model);
  Eigen::VectorXd phi(nc), nu(nc), gamma(nc);
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(nc, nq);
  eval.phi(q.data(), t, phi.data());
  eval.jacobian(q.data(), t, jac);
  eval.nu(q.data(), t, nu.data());
  eval.gamma(q.data(), qd.data(), t, gamma.data());
  std::string rows;
  for (int r = 0; r < nc; ++r) rows += (r ? ", " : "") + json_array(jac.row(r).transpose());
  // Outputs' values (format 6.4); a file without outputs keeps its v1 JSON.
  std::string outputs;
  if (model->programs().num_outputs > 0) {
    Eigen::VectorXd values(model->programs().num_outputs);
    kc::ProgramEvaluator<double> program(model->programs().outputs);
    program.run(q.data(), nullptr, t, model->params().data(), values.data());
    outputs = ", \"outputs\": " + json_array(values);
  }
  kc::OutputFile out("-");
  out.stream() << "{\"phi\": " << json_array(phi) << ", \"phi_q\": [" << rows
               << "], \"nu\": " << json_array(nu) << ", \"gamma\": " << json_array(gamma) << outputs
               << "}\n";
  out.commit();
  return 0;
}

std::string printf_text(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string printf_text(const char* format, ...) {
  char buf[512];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buf, sizeof buf, format, args);
  va_end(args);
  return buf;
}

int run_check(const Common& c, const kc::CheckOptions& options, bool structure) {
  if (!(std::abs(options.turns) <= kMaxCheckTurns) || !(std::abs(options.t) <= kMaxCheckTurns))
    throw kc::UsageError("--turns and --t must be within +-" + kc::format_number(kMaxCheckTurns) +
                         ": beyond it the inputs' rounding makes the bounds meaningless");
  const auto model = load(c, {}, false);
  if (options.samples < 1) throw kc::UsageError("--samples must be at least 1");
  kc::OutputFile file("-");
  std::ostream& out = file.stream();
  if (structure) out << kc::jacobian_structure(*model) << "\n";
  const auto rows = kc::check_derivatives(*model, options);
  out << printf_text("%-7s %-20s %12s %12s %10s  %s\n", "block", "method", "max abs", "max rel",
                     "bound", "result");
  bool ok = true;
  for (const auto& r : rows) {
    out << printf_text("%-7s %-20s %12.3e %12.3e %10.1e  %s\n", r.block.c_str(), r.method.c_str(),
                       r.max_abs, r.max_rel, r.bound, r.ok() ? "ok" : "FAILED");
    ok = ok && r.ok();
  }
  out << printf_text(
      "%d samples near q0 (seed %u, angles + 2 pi * %g); max rel = max abs / "
      "max(1, largest |truth| in the block)\n",
      options.samples, options.seed, options.turns);
  file.commit();
  if (!ok) {
    std::cerr << "error: " << c.file
              << ": check: the symbolic derivatives differ from the numeric ones beyond their "
                 "bounds\n";
    return kExitFailed;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
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
