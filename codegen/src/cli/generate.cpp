// `kinegen generate`: writes <DIR>/<name>.hpp, the C++ back end's header for a mechanism.
#include <filesystem>
#include <memory>
#include <string>

#include "cli.hpp"
#include "kinegen/codegen/base/log.hpp"
#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "kinegen/codegen/emit/reserved_names.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

namespace fs = std::filesystem;

namespace {

struct GenerateArgs {
  std::string dir = ".";
  bool fold_params = false;
  std::string name_space = "kinegen::models";
  std::string outputs = "acceleration";
  int max_function_ops = kc::kDefaultMaxFunctionOps;
  int roll_min = kc::kDefaultRollMin;
};

int run_generate(const Common& c, const GenerateArgs& o) {
  // A bad --namespace is a usage error before any work.
  if (const auto why = kc::namespace_conflict(o.name_space); !why.empty())
    throw kc::UsageError("--namespace: " + why);
  kc::BuildOptions build;
  build.fold_params = o.fold_params;
  const auto model = load(c, build, false);
  kc::StageScope stage("emitting C++");
  kc::EmitOptions options;
  if (o.outputs == "position") options.outputs = kc::Outputs::kPosition;
  if (o.outputs == "velocity") options.outputs = kc::Outputs::kVelocity;
  options.max_function_ops = o.max_function_ops;
  options.roll_min = o.roll_min;
  options.name_space = o.name_space;
  // A name the header cannot carry is refused before the structure is analyzed.
  kc::check_header_names(model->mechanism());
  const std::string text = kc::emit_header(*model, options);
  stage.done(std::to_string(text.size() / 1024) + " KiB");
  std::error_code ec;
  fs::create_directories(o.dir, ec);
  const fs::path target = fs::path(o.dir) / (model->mechanism().name + ".hpp");
  kc::OutputFile out(target.string());
  out.stream() << text;
  out.commit();
  kc::Log::global().info("wrote " + target.string() + " (nq = " + std::to_string(model->nq()) +
                         ", nc = " + std::to_string(model->nc()) + ", " +
                         std::to_string(model->programs().jac_rows.size()) +
                         " Jacobian non-zeros)");
  return 0;
}

}  // namespace

Subcommand add_generate(CLI::App& app, Common& common) {
  const auto o = std::make_shared<GenerateArgs>();
  auto* generate = app.add_subcommand("generate", "Write <DIR>/<name>.hpp for a mechanism");
  add_common(generate, common);
  generate->add_option("-o,--output", o->dir, "Output directory (default: .)");
  generate->add_flag("--fold-params", o->fold_params,
                     "Fold the parameter values (with --param overrides) into constants");
  generate->add_option("--namespace", o->name_space,
                       "C++ namespace of the model's struct (default kinegen::models); two models "
                       "of the same name need different ones to share a program");
  generate
      ->add_option("--outputs", o->outputs,
                   "Analyses the header supports: position (phi, phi_q), velocity (adds nu) or "
                   "acceleration (adds gamma; default)")
      ->check(CLI::IsMember({"position", "velocity", "acceleration"}));
  generate
      ->add_option("--max-function-ops", o->max_function_ops,
                   "Split generated functions with more operations than this (or more outputs "
                   "than a fifth of it) into parts, for compile time (default " +
                       std::to_string(kc::kDefaultMaxFunctionOps) + "; 0: never split)")
      ->check(CLI::NonNegativeNumber);
  generate
      ->add_option("--roll-min", o->roll_min,
                   "Emit Newton blocks that are alike up to their coordinates (the loops of a "
                   "chain) once, called with a table of coordinates, when at least this many are "
                   "alike (default " +
                       std::to_string(kc::kDefaultRollMin) + "; 0: never)")
      ->check(CLI::NonNegativeNumber);
  return {generate, [&common, o] { return run_generate(common, *o); }};
}

}  // namespace kinegen::cli
