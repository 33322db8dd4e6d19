// The cost of sensitivities in the in-process analysis (`kinegen analyze --sensitivity`).
//  1. End to end: ns per row of a 3601-row analysis without and with sensitivities to all the
//     example's parameters (interleaved runs, best of each), and the difference per parameter.
//  2. The parts, timed alone at a solved position: evaluating Phi_p (all parameters at once),
//     and one solve with an existing LU of Phi_q per parameter (what the analysis does through
//     the velocity's factorization), against the 3601-row step.
//  3. The generated headers (embedded use): ns per solve_step along a 3600-step crank turn
//     (from the previous step's q) against ns per solve_sensitivity at the same solved
//     positions (phi_q, phi_p and the block solve for all parameters), and that per parameter.
// Prints numbers; not a test. Run: build/bench/bench_sensitivity
#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "four_bar.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "offset_slider_crank.hpp"
#include "quick_return.hpp"
#include "slider_crank.hpp"

namespace cg = kinegen::codegen;

namespace {

using Clock = std::chrono::steady_clock;
constexpr int kSteps = 3600;
double sink = 0;

double ns_since(Clock::time_point start) {
  return std::chrono::duration<double, std::nano>(Clock::now() - start).count();
}

double ns_per_row(const cg::CompiledModel& model, const cg::SensitivityModel* sensitivity) {
  cg::AnalysisOptions options;
  options.sensitivity = sensitivity;
  const auto start = Clock::now();
  cg::run_analysis(
      model, {0, 2 * std::acos(-1.0), kSteps}, [&](const cg::StateRow& row) { sink += row.q[0]; },
      options);
  return ns_since(start) / (kSteps + 1);
}

template <class M>
void generated(const char* name) {
  const typename M::Params p{};
  const typename M::BlockOptions o{};
  const double dt = 2 * std::acos(-1.0) / kSteps;
  std::vector<double> qs((kSteps + 1) * M::nq), dq(M::nq * M::num_params);
  double q[M::nq], qd[M::nq], qdd[M::nq];
  std::copy(M::q0.begin(), M::q0.end(), q);
  double step = 1e300, sens = 1e300;
  for (int r = 0; r < 15; ++r) {
    std::copy(M::q0.begin(), M::q0.end(), q);
    auto start = Clock::now();
    for (int k = 0; k <= kSteps; ++k) {
      const auto report = M::solve_step(q, k * dt, p, qd, qdd, o);
      sink += report.status + qdd[0];
      std::copy(q, q + M::nq, qs.begin() + k * M::nq);
    }
    step = std::min(step, ns_since(start) / (kSteps + 1));
    start = Clock::now();
    for (int k = 0; k <= kSteps; ++k) {
      const auto report = M::solve_sensitivity(qs.data() + k * M::nq, k * dt, p, dq.data(), o);
      sink += report.status + dq[0];
    }
    sens = std::min(sens, ns_since(start) / (kSteps + 1));
  }
  std::printf("%-20s %6d %10.0f %10.0f %12.1f\n", name, M::num_params, step, sens,
              sens / M::num_params);
}

}  // namespace

int main() {
  std::printf("%-20s %6s %10s %10s %12s | %12s %14s\n", "model", "params", "step ns", "+sens ns",
              "ns/param", "phi_p ns", "solve ns/param");
  for (const char* name : {"slider_crank", "offset_slider_crank", "four_bar", "quick_return"}) {
    const auto model = cg::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/examples/" +
                                                    name + ".yaml");
    std::vector<std::string> params;
    for (const auto& p : model->mechanism().parameters) params.push_back(p.name);
    const auto sens = cg::build_sensitivity(*model, params);
    const int np = static_cast<int>(params.size());
    double plain = 1e300, with = 1e300;
    for (int r = 0; r < 15; ++r) {  // interleaved: drift of a shared machine hits both alike
      plain = std::min(plain, ns_per_row(*model, nullptr));
      with = std::min(with, ns_per_row(*model, &sens));
    }
    // The parts alone, at the solved position at t = 0.5.
    cg::StateRow solved;
    cg::run_analysis(*model, {0.5, 0.5, 0}, [&](const cg::StateRow& row) { solved = row; });
    cg::ProgramEvaluator<double> phi_p(sens.phi_p);
    cg::ModelEvaluator<double> eval(*model);
    Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(model->nc(), model->nq());
    eval.jacobian(solved.q.data(), 0.5, jac);
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(jac);
    Eigen::VectorXd out(static_cast<Eigen::Index>(model->nc()) * np), x(model->nq());
    constexpr int kReps = 20000;
    double phi_p_ns = 1e300, solve_ns = 1e300;
    for (int r = 0; r < 7; ++r) {
      auto start = Clock::now();
      for (int k = 0; k < kReps; ++k) {
        phi_p.run(solved.q.data(), nullptr, 0.5 + 1e-20 * k, model->params().data(), out.data());
        sink += out[0];
      }
      phi_p_ns = std::min(phi_p_ns, ns_since(start) / kReps);
      start = Clock::now();
      for (int k = 0; k < kReps; ++k) {
        x.noalias() = lu.solve(out.head(model->nc()));
        sink += x[0];
      }
      solve_ns = std::min(solve_ns, ns_since(start) / kReps);
    }
    std::printf("%-20s %6d %10.0f %10.0f %12.0f | %12.0f %14.0f\n", name, np, plain, with,
                (with - plain) / np, phi_p_ns, solve_ns);
  }
  std::printf(
      "\ngenerated headers (solve_step along the turn; solve_sensitivity at its positions)\n");
  std::printf("%-20s %6s %10s %10s %12s\n", "model", "params", "step ns", "sens ns", "ns/param");
  generated<kinegen::models::slider_crank>("slider_crank");
  generated<kinegen::models::offset_slider_crank>("offset_slider_crank");
  generated<kinegen::models::four_bar>("four_bar");
  generated<kinegen::models::quick_return>("quick_return");
  if (sink == 12345.678) std::puts("");  // keeps the work
}
