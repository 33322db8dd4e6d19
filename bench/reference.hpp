// The high-precision reference the work-precision benchmark measures errors against.
//
// When codegen provides run_reference_analysis (GiNaC/CLN, N digits) it is used. Otherwise a
// stand-in runs the same in-process programs in long double (64-bit mantissa) with a Newton
// tolerance of 1e-17, which is still ~3 digits beyond double; `reference_description` says
// which one ran, and the benchmark prints it.
#pragma once

#include <Eigen/Dense>
#include <kinegen/solver.hpp>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"

#if __has_include("kinegen/codegen/reference.hpp")
#include "kinegen/codegen/analysis/reference.hpp"
#define KINEGEN_BENCH_HAVE_CLN_REFERENCE 1
#else
#define KINEGEN_BENCH_HAVE_CLN_REFERENCE 0
#endif

namespace kinegen::bench {

inline constexpr int kReferenceDigits = 40;

inline std::string reference_description() {
  return KINEGEN_BENCH_HAVE_CLN_REFERENCE
             ? "GiNaC/CLN " + std::to_string(kReferenceDigits) +
                   "-digit analysis (run_reference_analysis)"
             : std::string(
                   "stand-in: long double analysis, Newton tolerance 1e-17 "
                   "(run_reference_analysis not available in this build)");
}

#if !KINEGEN_BENCH_HAVE_CLN_REFERENCE
// The in-process programs on long double.
class LongDoubleSystem {
 public:
  using Scalar = long double;
  static constexpr int kNq = Eigen::Dynamic;
  static constexpr int kNc = Eigen::Dynamic;
  explicit LongDoubleSystem(const codegen::CompiledModel& model) : model_(&model), eval_(model) {}
  LongDoubleSystem(const LongDoubleSystem& o) : model_(o.model_), eval_(*o.model_) {}
  int nq() const { return model_->nq(); }
  int nc() const { return model_->nc(); }
  double length_scale() const { return model_->symbolic().length_scale; }
  void phi(const Scalar* q, Scalar t, Scalar* out) const { eval_.phi(q, t, out); }
  void nu(const Scalar* q, Scalar t, Scalar* out) const { eval_.nu(q, t, out); }
  void gamma(const Scalar* q, const Scalar* qd, Scalar t, Scalar* out) const {
    eval_.gamma(q, qd, t, out);
  }
  template <class M>
  void jacobian(const Scalar* q, Scalar t, M& jac) const {
    eval_.jacobian(q, t, jac);
  }

 private:
  const codegen::CompiledModel* model_;
  mutable codegen::ModelEvaluator<long double> eval_;
};
#endif

// Reference rows (q, qd, qdd) at every time of `grid`.
inline std::vector<codegen::StateRow> reference_rows(const codegen::CompiledModel& model,
                                                     const codegen::TimeGrid& grid) {
  std::vector<codegen::StateRow> rows;
#if KINEGEN_BENCH_HAVE_CLN_REFERENCE
  codegen::run_reference_analysis(model, grid, kReferenceDigits,
                                  [&](const codegen::StateRow& row) { rows.push_back(row); });
#else
  using V = Eigen::Matrix<long double, Eigen::Dynamic, 1>;
  SolverOptions options;
  options.tolerance = 1e-17;
  options.max_iterations = 100;
  BasicSolver<LongDoubleSystem> solver(LongDoubleSystem(model), options);
  V q = model.q0().cast<long double>(), qd(q.size()), qdd(q.size());
  for (int k = 0; k <= grid.steps; ++k) {
    const long double t = grid.at(k);
    // From the previous solution, in small sub-steps so Newton stays on the branch.
    if (!solver.position(q, t)) throw std::runtime_error("reference: position failed");
    solver.velocity(q, t, qd);
    solver.acceleration(q, qd, t, qdd);
    codegen::StateRow row;
    row.t = grid.at(k);
    row.q = q.cast<double>();
    row.qd = qd.cast<double>();
    row.qdd = qdd.cast<double>();
    rows.push_back(row);
    if (k < grid.steps) {  // walk to the next time in small steps, as the benchmark does
      const double t_next = grid.at(k + 1);
      const int sub = 64;
      for (int s = 1; s < sub; ++s) {
        const long double ts = t + (t_next - t) * s / sub;
        if (!solver.position(q, ts)) throw std::runtime_error("reference: position failed");
      }
    }
  }
#endif
  return rows;
}

}  // namespace kinegen::bench
