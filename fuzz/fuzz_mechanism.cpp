// libFuzzer target: the loader, the expression parser, the symbolic pipeline, the emitter, the
// kinetostatics and the sensitivities on arbitrary text, then a short run of what the file asks
// for: four steps of `analyze` (the block program, StepFactors, the Newton policy, sub-steps),
// or for a file with `free:` a short `simulate` (the reduced dynamics on CVODE). Any input must
// end in a model and a run, an InputError or an AnalysisError; anything else (a crash, a
// sanitizer report, another exception, a hang) is a bug.
#include <cstddef>
#include <cstdint>
#include <string>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "kinegen/codegen/analysis/simulate.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/emit/emit_cpp.hpp"

namespace kc = kinegen::codegen;

namespace {

// A short run, bounded in work: 4 analysis steps, or 0.1 s of simulated motion with at most
// 2000 integrator steps.
void run(const kc::CompiledModel& model) {
  if (model.mechanism().num_free() == 0) {
    kc::run_analysis(model, {0, 1, 4}, [](const kc::StateRow&) {}, kc::AnalysisOptions{});
    return;
  }
  const kc::ForceModel forces = kc::derive_forces(model);
  kc::SimulateOptions options;
  options.rtol = 1e-6;
  options.max_steps = 2000;
  kc::run_simulation(model, forces, {0, 0.1, 4}, [](const kc::SimulatedRow&) {}, options);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // The loader rejects files above its size limit itself; keep the fuzzer's inputs near the
  // sizes of real mechanism files so time goes into structure, not length.
  if (size > 8192) return 0;
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    kc::BuildOptions build;
    build.free_as_state = true;  // as simulate builds it; a file without free: is unchanged
    auto model = kc::CompiledModel::from_mechanism(kc::parse_mechanism(text, "fuzz.yaml"), {},
                                                   build);
    (void)kc::emit_header(*model);
    // Evaluate once at q0 so the lowered programs run too.
    kc::ModelEvaluator<double> eval(*model);
    Eigen::VectorXd q = model->q0(), out(model->nc());
    Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(model->nc(), model->nq());
    eval.phi(q.data(), 0.5, out.data());
    eval.jacobian(q.data(), 0.5, jac);
    Eigen::VectorXd qd = Eigen::VectorXd::Ones(model->nq());
    eval.gamma(q.data(), qd.data(), 0.5, out.data());
    // The outputs: values, rates and accelerations.
    std::vector<std::array<double, 3>> outputs;
    kc::OutputEvaluator(*model).evaluate(0.5, q, qd, qd, outputs);
    // Masses and loads, then Phi_p for every parameter (what --forces and --sensitivity build).
    (void)kc::derive_forces(*model);
    std::vector<std::string> names;
    for (int k = 0; k < model->symbols().num_params() && k < 8; ++k)
      names.push_back(model->symbols().param_name(k));
    (void)kc::build_sensitivity(*model, names);
    run(*model);
  } catch (const kc::InputError&) {
    // Expected for invalid input.
  } catch (const kc::AnalysisError&) {
    // Expected for a mechanism that does not move as asked (a toggle, a lock-up).
  }
  return 0;
}
