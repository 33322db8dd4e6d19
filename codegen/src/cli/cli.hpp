// The cli stage: the `kinegen` command line. Each subcommand's file (generate.cpp, analyze.cpp,
// eval.cpp, check.cpp, animate.cpp, tolerance.cpp) registers its options (add_<name>) and runs
// it; main.cpp holds the global flags, the signal handlers, the parse, the dispatch, the mapping of
// errors to exit statuses, and the helpers declared here.
//
// Takes: argv. Gives: an exit status (0 success, 1 the analysis or a check failed, 2 invalid
// input or usage), files written atomically (io/output_file.hpp), one `error:` line per error.
// The only part of kinegen that prints besides errors (base/log.hpp).
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "kinegen/codegen/compile/compiled_model.hpp"

namespace kinegen::cli {

namespace kc = kinegen::codegen;

constexpr int kExitFailed = 1;
constexpr int kExitInvalid = 2;
constexpr int kExitInterrupted = 130;  // 128 + SIGINT, as a shell reports a run Ctrl-C ended

// The `error:` line of a run stopped by SIGINT (base/interrupt.hpp), and its exit status.
// `rows`: how many rows a streaming command wrote (and kept), or -1.
int interrupted(const std::string& file, long long rows = -1, double t_last = 0);

struct Common {
  std::string file;
  std::vector<std::string> params;
  std::vector<std::string> inputs;  // NAME=FILE.csv
  std::string command;              // the subcommand's name (main sets it before running it)
};

std::vector<kc::ParamOverride> parse_overrides(const std::vector<std::string>& args);

// Messages quote user text, which may hold line breaks; an error stays one line.
std::string one_line(std::string text);

// A --seed: decimal digits only, 0 to `max`; anything else (a sign, a fraction, a value beyond
// max) is a UsageError naming the range, never wrapped around.
std::uint64_t parse_seed(const std::string& text, std::uint64_t max);

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

// A run's warnings (AnalysisOptions::warn), as the log's `warning:` lines: one line each,
// silenced by --quiet like every other warning.
std::function<void(const std::string&)> warning_sink();

// A subcommand registered on the app. main runs `run` after the parse when `*command` is set:
// inside its try/catch, which turns exceptions into `error:` lines and exit statuses (a CLI11
// callback would run inside parse(), outside it).
struct Subcommand {
  CLI::App* command;
  std::function<int()> run;
};

// Each registers its subcommand and options on `app`; the options live as long as `run`.
// `common` must outlive it too.
Subcommand add_generate(CLI::App& app, Common& common);
Subcommand add_analyze(CLI::App& app, Common& common);
Subcommand add_eval(CLI::App& app, Common& common);
Subcommand add_check(CLI::App& app, Common& common);
Subcommand add_animate(CLI::App& app, Common& common);
Subcommand add_tolerance(CLI::App& app, Common& common);
Subcommand add_simulate(CLI::App& app, Common& common);
Subcommand add_view(CLI::App& app, Common& common);
Subcommand add_equilibrium(CLI::App& app, Common& common);
Subcommand add_modes(CLI::App& app, Common& common);
Subcommand add_linearize(CLI::App& app, Common& common);

}  // namespace kinegen::cli
