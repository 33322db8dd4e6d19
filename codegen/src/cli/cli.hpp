// The cli stage: the `kinegen` command line, one file per subcommand (generate.cpp,
// analyze.cpp, animate.cpp, tolerance.cpp, eval.cpp, check.cpp) and main.cpp (options,
// dispatch, errors).
//
// Takes: argv. Gives: an exit status (0 success, 1 the analysis or a check failed, 2 invalid
// input or usage), files written atomically (io/output_file.hpp), one `error:` line per error.
// The only part of kinegen that prints besides errors (base/log.hpp).
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/check.hpp"
#include "kinegen/codegen/analysis/compiled_model.hpp"
#include "kinegen/codegen/analysis/tolerance.hpp"
#include "kinegen/codegen/io/animate.hpp"

namespace kinegen::cli {

namespace kc = kinegen::codegen;

constexpr int kExitFailed = 1;
constexpr int kExitInvalid = 2;

struct Common {
  std::string file;
  std::vector<std::string> params;
  std::vector<std::string> inputs;  // NAME=FILE.csv
};

std::vector<kc::ParamOverride> parse_overrides(const std::vector<std::string>& args);

// Messages quote user text, which may hold line breaks; an error stays one line.
std::string one_line(std::string text);

// Every time t0 + k (t1 - t0) / N must be a number: finite ends and a finite span.
void check_grid(double t0, double t1, int steps);

// Reads and compiles the mechanism, its stages shown as the log's progress lines.
// Commands that run a motion (analyze, animate, tolerance) need every input driver as an
// --input table; generate keeps them (its code reads them from Params), and eval and check
// take them as 0, as a default Params does.
std::unique_ptr<kc::CompiledModel> load(const Common& c, kc::BuildOptions build = {},
                                        bool inputs_required = true);

// The positional mechanism file, --param and --input, which every subcommand takes.
void add_common(CLI::App* cmd, Common& c);

// A progress bar on a terminal (stderr), for long runs; empty when stderr is not a terminal
// or progress is off.
std::function<void(int, int)> terminal_progress(const std::string& what);

// The subcommands, one file each.
int run_generate(const Common& c, const std::string& dir, const std::string& outputs,
                 bool fold_params, int max_function_ops, int roll_min,
                 const std::string& name_space);
int run_animate(const Common& c, kc::AnimateOptions options, const std::string& output);
int run_analyze(const Common& c, double t0, double t1, int steps, const std::string& output,
                int reference_digits, bool strict, const std::string& sensitivity_list,
                bool with_forces, const std::string& solver);
int run_tolerance(const Common& c, kc::ToleranceOptions options,
                  const std::vector<std::string>& tol, const std::string& output);
int run_eval(const Common& c, double t, const std::vector<double>& q_arg,
             const std::vector<double>& qd_arg);
int run_check(const Common& c, const kc::CheckOptions& options, bool structure);

}  // namespace kinegen::cli
