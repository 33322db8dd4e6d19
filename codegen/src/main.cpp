// kinegen: generate | analyze | eval | check. Exit status: 0 success, 1 the analysis (or a
// check) failed, 2 invalid input or usage. Every error is one `error:` line on stderr.
#include <CLI/CLI.hpp>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <kinegen/solver.hpp>
#include <sstream>

#include "kinegen/codegen/analysis.hpp"
#include "kinegen/codegen/check.hpp"
#include "kinegen/codegen/emit_cpp.hpp"
#include "kinegen/codegen/model.hpp"

namespace kc = kinegen::codegen;
namespace fs = std::filesystem;

namespace {

constexpr int kExitFailed = 1;
constexpr int kExitInvalid = 2;

// Writes to a temporary file beside the target and renames it into place on commit, so the
// target is never half-written; an uncommitted file is removed.
class AtomicFile {
 public:
  explicit AtomicFile(fs::path target) : target_(std::move(target)) {
    temp_ = target_;
    temp_ += ".tmp-kinegen-" + std::to_string(::getpid());
    out_.open(temp_, std::ios::binary | std::ios::trunc);
    if (!out_) throw kc::UsageError("cannot write '" + target_.string() + "'");
  }
  ~AtomicFile() {
    if (!committed_) {
      out_.close();
      std::error_code ec;
      fs::remove(temp_, ec);
    }
  }
  std::ostream& stream() { return out_; }
  void commit() {
    out_.close();
    if (!out_) throw kc::UsageError("cannot write '" + target_.string() + "'");
    std::error_code ec;
    fs::rename(temp_, target_, ec);
    if (ec) throw kc::UsageError("cannot write '" + target_.string() + "': " + ec.message());
    committed_ = true;
  }

 private:
  fs::path target_, temp_;
  std::ofstream out_;
  bool committed_ = false;
};

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
};

void add_common(CLI::App* cmd, Common& c) {
  cmd->add_option("mechanism", c.file, "Mechanism file (YAML)")->required();
  cmd->add_option("--param", c.params, "Override a parameter: NAME=VALUE (repeatable)")
      ->type_name("NAME=VALUE");
}

int run_generate(const Common& c, const std::string& dir) {
  const auto model = kc::CompiledModel::from_file(c.file, parse_overrides(c.params));
  const std::string text = kc::emit_header(model->mechanism(), model->symbols(), model->symbolic(),
                                           model->programs());
  std::error_code ec;
  fs::create_directories(dir, ec);
  const fs::path target = fs::path(dir) / (model->mechanism().name + ".hpp");
  AtomicFile out(target);
  out.stream() << text;
  out.commit();
  std::cerr << "kinegen: wrote " << target.string() << " (nq = " << model->nq()
            << ", nc = " << model->nc() << ", " << model->programs().jac_rows.size()
            << " Jacobian non-zeros)\n";
  return 0;
}

int run_analyze(const Common& c, double t0, double t1, int steps, const std::string& output,
                bool strict) {
  const auto model = kc::CompiledModel::from_file(c.file, parse_overrides(c.params));
  kc::require_driven(*model);
  if (steps < 0) throw kc::UsageError("--steps must be 0 or more");
  if (!std::isfinite(t0) || !std::isfinite(t1)) throw kc::UsageError("--t0 and --t1 must be finite");
  std::unique_ptr<AtomicFile> file;
  if (!output.empty()) file = std::make_unique<AtomicFile>(output);
  std::ostream& out = file ? file->stream() : std::cout;
  out << kc::csv_header(model->mechanism());
  int status = 0;
  int rows = 0;
  try {
    kc::AnalysisOptions options;
    options.strict = strict;
    options.warn = [](const std::string& w) { std::cerr << "warning: " << one_line(w) << "\n"; };
    kc::run_analysis(*model, {t0, t1, steps},
                     [&](const kc::StateRow& row) {
                       out << kc::csv_row(row);
                       ++rows;
                     },
                     options);
  } catch (const kc::AnalysisError& e) {
    std::cerr << "error: " << one_line(e.what()) << "\n";
    status = kExitFailed;  // the rows solved so far are kept
  }
  out.flush();
  if (file && (rows > 0 || status == 0)) file->commit();  // nothing solved: nothing to keep
  return status;
}

int run_eval(const Common& c, double t, const std::vector<double>& q_arg,
             const std::vector<double>& qd_arg) {
  const auto model = kc::CompiledModel::from_file(c.file, parse_overrides(c.params));
  const int nq = model->nq(), nc = model->nc();
  const Eigen::VectorXd q = q_arg.empty() ? model->q0() : vector_arg(q_arg, nq, "--q");
  const Eigen::VectorXd qd = qd_arg.empty() ? Eigen::VectorXd::Zero(nq) : vector_arg(qd_arg, nq, "--qd");
  kc::ModelEvaluator<double> eval(*model);
  Eigen::VectorXd phi(nc), nu(nc), gamma(nc);
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(nc, nq);
  eval.phi(q.data(), t, phi.data());
  eval.jacobian(q.data(), t, jac);
  eval.nu(q.data(), t, nu.data());
  eval.gamma(q.data(), qd.data(), t, gamma.data());
  std::string rows;
  for (int r = 0; r < nc; ++r) rows += (r ? ", " : "") + json_array(jac.row(r).transpose());
  std::cout << "{\"phi\": " << json_array(phi) << ", \"phi_q\": [" << rows
            << "], \"nu\": " << json_array(nu) << ", \"gamma\": " << json_array(gamma) << "}\n";
  return 0;
}

int run_check(const Common& c, const kc::CheckOptions& options, bool structure) {
  const auto model = kc::CompiledModel::from_file(c.file, parse_overrides(c.params));
  if (options.samples < 1) throw kc::UsageError("--samples must be at least 1");
  if (structure) std::cout << kc::jacobian_structure(*model) << "\n";
  const auto rows = kc::check_derivatives(*model, options);
  std::printf("%-7s %-20s %12s %12s %10s  %s\n", "block", "method", "max abs", "max rel", "bound",
              "result");
  bool ok = true;
  for (const auto& r : rows) {
    std::printf("%-7s %-20s %12.3e %12.3e %10.1e  %s\n", r.block.c_str(), r.method.c_str(),
                r.max_abs, r.max_rel, r.bound, r.ok() ? "ok" : "FAILED");
    ok = ok && r.ok();
  }
  std::printf("%d samples near q0 (seed %u); max rel = max abs / max(1, largest |numeric|)\n",
              options.samples, options.seed);
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

  Common common;
  std::string out_dir = ".";
  auto* generate = app.add_subcommand("generate", "Write <DIR>/<name>.hpp for a mechanism");
  add_common(generate, common);
  generate->add_option("-o,--output", out_dir, "Output directory (default: .)");

  double t0 = 0, t1 = 0;
  int steps = 0;
  std::string csv;
  auto* analyze = app.add_subcommand("analyze", "Position, velocity and acceleration over time");
  add_common(analyze, common);
  analyze->add_option("--t0", t0, "Start time")->required();
  analyze->add_option("--t1", t1, "End time")->required();
  analyze->add_option("--steps", steps, "Number of steps N (N + 1 rows)")->required();
  analyze->add_option("-o,--output", csv, "CSV file (default: standard output)");
  bool strict = false;
  analyze->add_flag("--strict", strict, "Redundant constraints are an error (exit 2), not a warning");

  double t = 0;
  std::vector<double> q_arg, qd_arg;
  auto* eval = app.add_subcommand("eval", "Print Phi, Phi_q, nu and gamma as JSON");
  add_common(eval, common);
  eval->add_option("--t", t, "Time (default 0)");
  eval->add_option("--q", q_arg, "Coordinates (default: q0)")->delimiter(',')->allow_extra_args(false);
  eval->add_option("--qd", qd_arg, "Velocities (default: zeros)")->delimiter(',')->allow_extra_args(false);

  kc::CheckOptions check_options;
  bool structure = false;
  auto* check = app.add_subcommand("check", "Compare Phi_q, nu and gamma with numeric derivatives");
  add_common(check, common);
  check->add_option("--samples", check_options.samples, "Random configurations (default 5)");
  check->add_option("--seed", check_options.seed, "Random seed (default 1)");
  check->add_option("--t", check_options.t, "Time around which to sample (default 0)");
  check->add_flag("--structure", structure, "Also print the structure of Phi_q");

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

  try {
    if (*generate) return run_generate(common, out_dir);
    if (*analyze) return run_analyze(common, t0, t1, steps, csv, strict);
    if (*eval) return run_eval(common, t, q_arg, qd_arg);
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
  } catch (const std::exception& e) {
    std::cerr << "error: " << one_line(common.file + ": internal error: " + e.what()) << "\n";
    return kExitFailed;
  }
  return 0;
}
