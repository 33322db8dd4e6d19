// `kinegen check`: the derivative blocks against complex step, central differences and CLN.
#include "kinegen/codegen/analysis/check.hpp"

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>
#include <string>

#include "cli.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

namespace {

// `check --turns K` and `--t`: beyond this the inputs' own rounding (eps * 2 pi K rad) makes the
// derivative bounds grow to meaninglessness; at 1e7 turns an angle is known to 1.4e-8 rad and
// the central-difference bound is 6e-4 (docs/stability.md).
constexpr double kMaxCheckTurns = 1e7;

std::string printf_text(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string printf_text(const char* format, ...) {
  char buf[512];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buf, sizeof buf, format, args);
  va_end(args);
  return buf;
}

struct CheckArgs {
  kc::CheckOptions check;
  std::string seed = "1";
  bool structure = false;
};

int run_check(const Common& c, const CheckArgs& o) {
  kc::CheckOptions options = o.check;
  options.seed =
      static_cast<unsigned>(parse_seed(o.seed, std::numeric_limits<decltype(options.seed)>::max()));
  if (!(std::abs(options.turns) <= kMaxCheckTurns) || !(std::abs(options.t) <= kMaxCheckTurns))
    throw kc::UsageError("--turns and --t must be within +-" + kc::format_number(kMaxCheckTurns) +
                         ": beyond it the inputs' rounding makes the bounds meaningless");
  const auto model = load(c, {}, false);
  if (options.samples < 1) throw kc::UsageError("--samples must be at least 1");
  kc::OutputFile file("-");
  std::ostream& out = file.stream();
  if (o.structure) out << kc::jacobian_structure(*model) << "\n";
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

Subcommand add_check(CLI::App& app, Common& common) {
  const auto o = std::make_shared<CheckArgs>();
  auto* check = app.add_subcommand("check", "Compare Phi_q, nu and gamma with numeric derivatives");
  add_common(check, common);
  check->add_option("--samples", o->check.samples, "Random configurations (default 5)");
  check->add_option("--seed", o->seed, "Random seed, 0 to 4294967295 (default 1)");
  check->add_option("--t", o->check.t, "Time around which to sample (default 0)");
  check->add_flag("--structure", o->structure, "Also print the structure of Phi_q");
  check->add_option("--turns", o->check.turns,
                    "Shift every angle by 2 pi K: check after many revolutions (default 0)");
  check->add_option("--digits", o->check.digits, "Decimal digits of the CLN method (default 40)");
  return {check, [&common, o] { return run_check(common, *o); }};
}

}  // namespace kinegen::cli
