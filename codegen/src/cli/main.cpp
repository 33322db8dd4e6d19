// kinegen: generate | analyze | eval | check | animate | tolerance. Exit status: 0 success, 1 the
// analysis (or a check) failed, 2 invalid input or usage, 130 interrupted (SIGINT). Every error is
// one `error:` line on stderr. This file: the global flags (-q, -v, --version), the parse, the
// dispatch, the errors, and the helpers the subcommands share (cli.hpp); each subcommand's options
// and run are in its own file (add_<name>).
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <iostream>

#include "cli.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/base/log.hpp"
#include "kinegen/codegen/base/version.hpp"
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

std::uint64_t parse_seed(const std::string& text, std::uint64_t max) {
  std::uint64_t value = 0;
  bool ok = !text.empty() && text.size() <= 20;
  for (const char ch : text) {
    if (!ok) break;
    const auto digit = static_cast<std::uint64_t>(ch - '0');
    ok = ch >= '0' && ch <= '9' && value <= (max - digit) / 10;
    value = value * 10 + digit;
  }
  if (!ok)
    throw kc::UsageError("--seed must be a whole number from 0 to " + std::to_string(max) +
                         ", not '" + text + "'");
  return value;
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
  // The commands that take spatial files so far (docs/format.md, Spatial mechanisms).
  build.spatial = c.command == "eval" || c.command == "check" || c.command == "analyze" ||
                  c.command == "generate" || c.command == "view" || c.command == "tolerance";
  build.user = "`kinegen " + c.command + "`";
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
                  "A run-time input's values, of an input driver (f: input) or a load's input: "
                  "NAME=FILE.csv, columns t,value, interpolated as a table (repeatable)")
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

int interrupted(const std::string& file, long long rows, double t_last) {
  std::string message = file + ": interrupted (SIGINT)";
  if (rows > 0)
    message += " after " + std::to_string(rows) + " rows, the last at " + kc::format_time(t_last) +
               "; they are kept";
  else if (rows == 0)
    message += " before the first row";
  std::cerr << "error: " << one_line(message) << "\n";
  return kExitInterrupted;
}

std::function<void(const std::string&)> warning_sink() {
  return [](const std::string& w) { kc::Log::global().warning(one_line(w)); };
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

  // In this order in --help.
  Common common;
  const std::vector<Subcommand> subs = {
      add_generate(app, common), add_analyze(app, common), add_eval(app, common),
      add_check(app, common),    add_animate(app, common), add_tolerance(app, common),
      add_simulate(app, common), add_equilibrium(app, common), add_modes(app, common),
      add_linearize(app, common), add_view(app, common),
  };

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

  kc::install_signal_handlers();  // Ctrl-C stops a run at its next row (interrupted())
  kc::Log::global().set_verbosity(quiet     ? kc::Verbosity::kQuiet
                                  : verbose ? kc::Verbosity::kVerbose
                                            : kc::Verbosity::kNormal);
  try {
    for (const auto& s : subs)
      if (*s.command) {
        common.command = s.command->get_name();
        return s.run();
      }
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
  } catch (const kc::Interrupted&) {
    return interrupted(common.file);  // nothing is written: no file was committed
  } catch (const std::exception& e) {
    std::cerr << "error: " << one_line(common.file + ": internal error: " + e.what()) << "\n";
    return kExitFailed;
  }
  return 0;
}
