// `kinegen generate`: writes <DIR>/<name>.hpp, the C++ back end's header for a mechanism.
#include <filesystem>
#include <string>

#include "cli.hpp"
#include "kinegen/codegen/base/log.hpp"
#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "kinegen/codegen/emit/reserved_names.hpp"
#include "kinegen/codegen/io/output_file.hpp"

namespace kinegen::cli {

namespace fs = std::filesystem;

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

}  // namespace kinegen::cli
