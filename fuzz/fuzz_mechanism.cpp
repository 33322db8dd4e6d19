// libFuzzer target: the loader, the expression parser, the symbolic pipeline, the emitter, the
// kinetostatics and the sensitivities on arbitrary text, then a short run of what the file asks
// for: four steps of `analyze` (the block program, StepFactors, the Newton policy, sub-steps;
// spatial files' continuation and branch checks; a suspension: block's design solve and rows), or
// for a file with `free:` a short `simulate` (its stop_when, breakpoints, energy bound and force
// columns) by one of the methods and tolerances, sometimes the high-precision reference, then what
// `linearize`, `modes` and `equilibrium` do at t0. The run's settings come from a hash of the
// input, so that mutations reach each of them. Any input must end in a model and a run, an
// InputError, a UsageError or an AnalysisError; anything else (a crash, a sanitizer report, another
// exception, a hang) is a bug.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/equilibrium.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/linearize.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/analysis/reference_dynamics.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "kinegen/codegen/analysis/simulate.hpp"
#include "kinegen/codegen/analysis/suspension.hpp"
#include "kinegen/codegen/analysis/tangent.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/emit/emit_cpp.hpp"

namespace kc = kinegen::codegen;

namespace {

// A short run, bounded in work: 4 analysis steps, or 0.1 s of simulated motion with at most
// 2000 integrator steps (the reference: 0.01 s, 20 steps), then the linear analyses at t0.
// `choice` (a hash of the input) picks the method, the integrator, the tolerances, the force
// columns and, once in 16, the reference.
void run(const kc::CompiledModel& model, unsigned choice) {
  if (model.mechanism().num_free() == 0) {
    // A suspension: block adds its design solve and, per row, the travel from it and the
    // motion ratios over the run.
    std::unique_ptr<kc::SuspensionRows> suspension;
    if (model.mechanism().suspension)
      suspension = std::make_unique<kc::SuspensionRows>(model, kc::AnalysisOptions{});
    std::vector<kc::StateRow> rows;
    kc::run_analysis(
        model, {0, 1, 4},
        [&](const kc::StateRow& row) {
          rows.push_back(row);
          if (suspension) suspension->apply(rows.back());
        },
        kc::AnalysisOptions{});
    if (suspension) (void)suspension->motion_ratios(rows);
    return;
  }
  const kc::ForceModel forces = kc::derive_forces(model);
  static const double kRtols[] = {1e-6, 1e-8, 1e-11, 1e-3};
  kc::SimulateOptions options = kc::simulate_options(
      kRtols[choice % 4], std::nullopt, (choice >> 2) % 3 == 2 ? "augmented" : "minimal",
      ((choice >> 4) % 3 == 0) ? "auto" : ((choice >> 4) % 3 == 1 ? "bdf" : "adams"), "--");
  options.max_steps = 2000;
  if ((choice >> 6) % 2) options.forces_columns = &forces;
  if ((choice >> 7) % 4 == 0) options.max_step = 1e-3;
  if ((choice >> 9) % 16 == 0) {
    // 20 steps: 200 took 28-70 s on Andrews' seven bodies under the sanitizers, and the
    // reference's code is the same after its first steps.
    options.max_steps = 20;
    kc::run_reference_simulation(
        model, forces, {0, 0.01, 2}, 16, [](const kc::SimulatedRow&) {}, options);
  } else {
    kc::run_simulation(
        model, forces, {0, 0.1, 4}, [](const kc::SimulatedRow&) {}, options);
  }
  kc::Linearizer linearizer(model, forces, 0);
  const kc::OperatingPoint p = linearizer.initial();
  (void)kc::linearize(linearizer, p);
  (void)kc::modal_analysis(linearizer, p);
  (void)kc::find_equilibrium(linearizer, p, kc::EquilibriumSearch::kNearest, 20);
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
    auto model =
        kc::CompiledModel::from_mechanism(kc::parse_mechanism(text, "fuzz.yaml"), {}, build);
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
    run(*model, static_cast<unsigned>(std::hash<std::string>{}(text)));
  } catch (const kc::InputError&) {
    // Expected for invalid input.
  } catch (const kc::UsageError&) {
    // Expected where a setting does not apply to the file (the augmented method without
    // free coordinates to move, a reference with more breakpoints than it takes).
  } catch (const kc::AnalysisError&) {
    // Expected for a mechanism that does not move as asked (a toggle, a lock-up).
  }
  return 0;
}
