// Work-precision benchmark: time per full analysis step (position by Newton from the previous
// solution, then velocity and acceleration) against the largest error versus a high-precision
// reference, over a long run, for every example and several methods:
//   generated          generated Phi, Phi_q, nu, gamma through kinegen::Solver<Model>
//   finite-difference  the same Newton; Phi_q, nu, gamma by central differences of generated phi
//   complex-step       the same Newton; Phi_q, nu by complex step of generated phi<complex>,
//                      gamma by the 45-degree complex step for second derivatives
//   generic            a DADS-style solver: joint records evaluated at run time (no codegen)
//   solvespace, simbody  peers (when found at configure time), slider_crank and four_bar
// at Newton tolerances 1e-4 .. 1e-14. All in this one process, single thread, so ratios are
// meaningful. Prints a table and writes a CSV. Not a test.
//
// Usage: bench_work_precision [CSV] [--quick]
#include <Eigen/Dense>
#include <array>
#include <complex>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <kinegen/solver.hpp>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "four_bar.hpp"
#include "generic_from_mechanism.hpp"
#include "generic_solver.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "offset_slider_crank.hpp"
#include "quick_return.hpp"
#include "reference.hpp"
#include "slider_crank.hpp"
#include "slider_crank_lecture.hpp"
#include "work_precision.hpp"

namespace kinegen::bench {
namespace {

constexpr std::array<double, 6> kTolerances = {1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14};
constexpr double kDefaultTolerance = 1e-10;  // the runtime's default: the ratios' baseline

// Phi from the generated code; Phi_q, nu and gamma by central differences.
//   Phi_q column k: step h_k = eps^(1/3) * max(|q_k|, s_k), s_k = the coordinate's scale
//   nu = -Phi_t:    step eps^(1/3) * max(|t|, 1)
//   gamma = -d^2/ds^2 Phi(q + s qd, t + s) at s = 0: second central difference, h = 2^-13
//   (about eps^(1/4); a power of two so that t +- h is exact on the benchmark's grid)
template <class Model>
class FiniteDifferenceSystem {
 public:
  using Scalar = double;
  static constexpr int kNq = Model::nq, kNc = Model::nc;
  int nq() const { return kNq; }
  int nc() const { return kNc; }
  double length_scale() const { return Model::length_scale; }
  double coordinate_scale(int k) const { return detail::model_coordinate_scale<Model>(k); }

  void phi(const double* q, double t, double* out) const { Model::phi(q, t, params_, out); }
  template <class M>
  void jacobian(const double* q, double t, M& jac) const {
    const double eps3 = std::cbrt(std::numeric_limits<double>::epsilon());
    std::array<double, kNq> x;
    std::array<double, kNc> fp, fm;
    std::copy(q, q + kNq, x.begin());
    for (int k = 0; k < kNq; ++k) {
      const double s = detail::model_coordinate_scale<Model>(k);
      const double h = eps3 * std::max(std::abs(q[k]), s);
      x[k] = q[k] + h;
      const double hp = x[k] - q[k];
      Model::phi(x.data(), t, params_, fp.data());
      x[k] = q[k] - h;
      const double hm = q[k] - x[k];
      Model::phi(x.data(), t, params_, fm.data());
      x[k] = q[k];
      for (int r = 0; r < kNc; ++r) jac(r, k) = (fp[r] - fm[r]) / (hp + hm);
    }
  }
  void nu(const double* q, double t, double* out) const {
    const double h = std::cbrt(std::numeric_limits<double>::epsilon()) * std::max(std::abs(t), 1.0);
    std::array<double, kNc> fp, fm;
    Model::phi(q, t + h, params_, fp.data());
    Model::phi(q, t - h, params_, fm.data());
    const double span = (t + h) - (t - h);
    for (int r = 0; r < kNc; ++r) out[r] = -(fp[r] - fm[r]) / span;
  }
  void gamma(const double* q, const double* qd, double t, double* out) const {
    const double h = 1.0 / 8192;
    std::array<double, kNq> xp, xm;
    std::array<double, kNc> fp, f0, fm;
    for (int k = 0; k < kNq; ++k) {
      xp[k] = q[k] + h * qd[k];
      xm[k] = q[k] - h * qd[k];
    }
    Model::phi(xp.data(), t + h, params_, fp.data());
    Model::phi(q, t, params_, f0.data());
    Model::phi(xm.data(), t - h, params_, fm.data());
    for (int r = 0; r < kNc; ++r) out[r] = -(fp[r] - 2 * f0[r] + fm[r]) / (h * h);
  }

 private:
  typename Model::Params params_{};
};

// Phi from the generated code instantiated with std::complex<double>.
//   Phi_q column k = Im Phi(q + i h e_k) / h, nu = -Im Phi(q, t + i h) / h, h = 1e-30 (exact
//   to rounding: no subtraction).
//   gamma: the second derivative along (qd, 1) by the 45-degree complex step (Lai & Crassidis
//   2008): f''(0) ~ Im[f(w h) + f(-w h)] / h^2, w = exp(i pi/4); truncation O(h^4), rounding
//   O(eps/h), so h = 2^-10 (about eps^(1/5)).
template <class Model>
class ComplexStepSystem {
 public:
  using Scalar = double;
  using C = std::complex<double>;
  static constexpr int kNq = Model::nq, kNc = Model::nc;
  int nq() const { return kNq; }
  int nc() const { return kNc; }
  double length_scale() const { return Model::length_scale; }
  double coordinate_scale(int k) const { return detail::model_coordinate_scale<Model>(k); }

  void phi(const double* q, double t, double* out) const { Model::phi(q, t, params_, out); }
  template <class M>
  void jacobian(const double* q, double t, M& jac) const {
    constexpr double h = 1e-30;
    std::array<C, kNq> x;
    std::array<C, kNc> f;
    for (int k = 0; k < kNq; ++k) x[k] = q[k];
    for (int k = 0; k < kNq; ++k) {
      x[k] = C(q[k], h);
      Model::phi(x.data(), C(t), params_, f.data());
      x[k] = q[k];
      for (int r = 0; r < kNc; ++r) jac(r, k) = f[r].imag() / h;
    }
  }
  void nu(const double* q, double t, double* out) const {
    constexpr double h = 1e-30;
    std::array<C, kNq> x;
    std::array<C, kNc> f;
    for (int k = 0; k < kNq; ++k) x[k] = q[k];
    Model::phi(x.data(), C(t, h), params_, f.data());
    for (int r = 0; r < kNc; ++r) out[r] = -f[r].imag() / h;
  }
  void gamma(const double* q, const double* qd, double t, double* out) const {
    constexpr double h = 1.0 / 1024;
    const C w = C(std::sqrt(0.5), std::sqrt(0.5)) * h;
    std::array<C, kNq> xp, xm;
    std::array<C, kNc> fp, fm;
    for (int k = 0; k < kNq; ++k) {
      xp[k] = q[k] + w * qd[k];
      xm[k] = q[k] - w * qd[k];
    }
    Model::phi(xp.data(), t + w, params_, fp.data());
    Model::phi(xm.data(), t - w, params_, fm.data());
    for (int r = 0; r < kNc; ++r) out[r] = -(fp[r].imag() + fm[r].imag()) / (h * h);
  }

 private:
  typename Model::Params params_{};
};

// Times a BasicSolver-like solver over the grid, recording the samples at reference times.
template <class SolverT>
RunResult run_solver(const std::string& method, const std::string& setting, SolverT& solver,
                     const typename SolverT::Vector& q0, const BenchGrid& g) {
  using Vector = typename SolverT::Vector;
  RunResult result;
  result.method = method;
  result.setting = setting;
  Vector q = q0, qd = q0, qdd = q0;
  std::vector<Sample> samples;
  double fail_t = NAN;
  auto step = [&](int k, bool record) {
    const double t = g.grid.at(k);
    if (!solver.position(q, t)) {
      fail_t = t;
      return false;
    }
    solver.velocity(q, t, qd);
    solver.acceleration(q, qd, t, qdd);
    if (record) samples.push_back(Sample{q, qd, qdd});
    return true;
  };
  result.ns_per_step = time_steps(g, step, [&] {
    q = q0;
    samples.clear();
  });
  if (std::isnan(result.ns_per_step)) {
    result.ok = false;
    std::ostringstream why;
    why << "position solve failed at t = " << fail_t;
    result.note = why.str();
  }
  result.samples = std::move(samples);
  return result;
}

std::string tolerance_label(double tol) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "tol=%.0e", tol);
  return buf;
}

// Largest difference between the generic system and the generated code at random states, so a
// wrong joint formula in the baseline cannot pass unnoticed.
template <class Model>
double generic_self_check(const generic::GenericSystem& sys) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2, 2);
  typename Model::Params p{};
  double worst = 0;
  for (int trial = 0; trial < 5; ++trial) {
    std::array<double, Model::nq> q, qd;
    for (auto& v : q) v = u(rng);
    for (auto& v : qd) v = u(rng);
    const double t = u(rng);
    std::array<double, Model::nc> a, b;
    Model::phi(q.data(), t, p, a.data());
    sys.phi(q.data(), t, b.data());
    for (int r = 0; r < Model::nc; ++r) worst = std::max(worst, std::abs(a[r] - b[r]));
    Model::nu(q.data(), t, p, a.data());
    sys.nu(q.data(), t, b.data());
    for (int r = 0; r < Model::nc; ++r) worst = std::max(worst, std::abs(a[r] - b[r]));
    Model::gamma(q.data(), qd.data(), t, p, a.data());
    sys.gamma(q.data(), qd.data(), t, b.data());
    for (int r = 0; r < Model::nc; ++r) worst = std::max(worst, std::abs(a[r] - b[r]));
    Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(Model::nc, Model::nq), gen = dense;
    sys.jacobian(q.data(), t, dense);
    std::array<double, Model::jac_nnz> vals;
    Model::phi_q(q.data(), t, p, vals.data());
    for (int k = 0; k < Model::jac_nnz; ++k) gen(Model::jac_rows[k], Model::jac_cols[k]) = vals[k];
    worst = std::max(worst, (dense - gen).cwiseAbs().maxCoeff());
  }
  return worst;
}

struct Report {
  std::string example;
  std::vector<double> scales;  // per coordinate (coordinate_scales)
  RunResult run;
  Errors err;
};

class Bench {
 public:
  Bench(BenchGrid g, bool with_fd_cs_generic) : g_(g), all_methods_(with_fd_cs_generic) {}

  template <class Model>
  void example(const std::string& name) {
    std::printf("\n== %s (nq = %d) ==\n", name.c_str(), Model::nq);
    std::fflush(stdout);
    const auto model = codegen::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                         "/examples/" + name + ".yaml");
    const auto ref_start = std::chrono::steady_clock::now();
    const codegen::TimeGrid rg{g_.reference_grid().t0, g_.reference_grid().t1,
                               g_.reference_grid().steps};
    std::vector<Sample> ref;
    for (const auto& row : reference_rows(*model, rg))
      ref.push_back(Sample{row.q, row.qd, row.qdd});
    const double ref_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - ref_start).count();
    std::printf("reference: %zu times in %.1f s\n", ref.size(), ref_s);
    std::vector<double> L;  // the coordinates' scales, as the solvers measure them
    for (int k = 0; k < Model::nq; ++k) L.push_back(detail::model_coordinate_scale<Model>(k));

    // Every kinegen method and setting is a job; the repetitions are interleaved (each
    // repetition runs every job once) so that a change of machine load during the run does
    // not favour one method. The best time of each job counts.
    using Job = std::function<RunResult(const BenchGrid&)>;
    std::vector<Job> jobs;
    for (double tol : kTolerances)
      jobs.push_back([tol](const BenchGrid& g) {
        SolverOptions opt;
        opt.tolerance = tol;
        Solver<Model> solver(typename Model::Params{}, opt);
        return run_solver("generated", tolerance_label(tol), solver, solver.initial_estimate(), g);
      });
    if (all_methods_) {
      for (double tol : kTolerances)
        jobs.push_back([tol](const BenchGrid& g) {
          SolverOptions opt;
          opt.tolerance = tol;
          BasicSolver<FiniteDifferenceSystem<Model>> solver(FiniteDifferenceSystem<Model>{}, opt);
          return run_solver("finite-difference", tolerance_label(tol), solver,
                            Solver<Model>::initial_estimate(), g);
        });
      for (double tol : kTolerances)
        jobs.push_back([tol](const BenchGrid& g) {
          SolverOptions opt;
          opt.tolerance = tol;
          BasicSolver<ComplexStepSystem<Model>> solver(ComplexStepSystem<Model>{}, opt);
          return run_solver("complex-step", tolerance_label(tol), solver,
                            Solver<Model>::initial_estimate(), g);
        });
    }
    std::string why;
    const auto data = generic::from_compiled_model(*model, why);
    std::optional<generic::GenericSystem> sys;
    if (!all_methods_) {
    } else if (!data) {
      std::printf("generic: skipped for %s: %s\n", name.c_str(), why.c_str());
    } else {
      sys.emplace(*data);
      const double diff = generic_self_check<Model>(*sys);
      std::printf("generic: joint-library evaluation vs generated code, max |diff| %.2e\n", diff);
      if (!(diff < 1e-12)) {
        std::printf("generic: FAILED its self-check; not timed\n");
      } else {
        for (double tol : kTolerances)
          jobs.push_back([tol, &sys, &data](const BenchGrid& g) {
            SolverOptions opt;
            opt.tolerance = tol;
            generic::GenericSolver solver(*sys, opt);
            return run_solver("generic", tolerance_label(tol), solver, data->q0, g);
          });
      }
    }
    BenchGrid once = g_;
    once.repetitions = 1;
    std::vector<RunResult> best(jobs.size());
    for (int rep = 0; rep < g_.repetitions; ++rep)
      for (std::size_t i = 0; i < jobs.size(); ++i) {
        RunResult r = jobs[i](once);
        if (rep == 0)
          best[i] = std::move(r);
        else if (best[i].ok && r.ok)
          best[i].ns_per_step = std::min(best[i].ns_per_step, r.ns_per_step);
      }
    for (auto& r : best) add(name, L, ref, std::move(r));
    if (name == "slider_crank" || name == "four_bar") {
      for (auto* peer : {&run_solvespace, &run_simbody}) {
        std::string skipped;
        // A peer run takes tens of seconds per setting: one repetition is enough for timing.
        BenchGrid once = g_;
        once.repetitions = 1;
        for (auto& r : peer(name, once, skipped)) add(name, L, ref, std::move(r));
        if (!skipped.empty()) std::printf("%s\n", skipped.c_str());
      }
    }
  }

  void write_csv(const std::string& path) const {
    std::ofstream out(path);
    out << "example,method,setting,ns_per_step,err_q,err_v,err_a,err_max,status\n";
    out.precision(6);
    for (const auto& r : reports_) {
      out << r.example << ',' << r.run.method << ',' << r.run.setting << ',' << r.run.ns_per_step
          << ',' << r.err.q << ',' << r.err.v << ',' << r.err.a << ',' << r.err.max() << ','
          << (r.run.ok ? "ok" : "failed") << '\n';
    }
  }

  // Ratios to the generated code at the default tolerance, per example, for each method's
  // setting with the smallest error (and at the default tolerance for kinegen's baselines).
  void print_ratios() const {
    std::printf("\nRatios against generated code (tol=1e-10), same run:\n");
    std::printf("%-22s %-18s %-10s %10s %12s %12s\n", "example", "method", "setting", "time ratio",
                "error", "generated err");
    for (const auto& base : reports_) {
      if (base.run.method != "generated" || base.run.setting != tolerance_label(kDefaultTolerance))
        continue;
      for (const auto& r : reports_) {
        if (r.example != base.example || r.run.method == "generated") continue;
        const bool peer = r.run.method == "solvespace" || r.run.method == "simbody";
        if (!peer && r.run.setting != tolerance_label(kDefaultTolerance)) continue;
        if (!r.run.ok) {
          std::printf("%-22s %-18s %-10s %10s\n", r.example.c_str(), r.run.method.c_str(),
                      r.run.setting.c_str(), "failed");
          continue;
        }
        std::printf("%-22s %-18s %-10s %9.2fx %12.2e %12.2e\n", r.example.c_str(),
                    r.run.method.c_str(), r.run.setting.c_str(),
                    r.run.ns_per_step / base.run.ns_per_step, r.err.max(), base.err.max());
      }
    }
  }

 private:
  void add(const std::string& example, const std::vector<double>& L, const std::vector<Sample>& ref,
           RunResult run) {
    Report rep{example, L, std::move(run), {}};
    if (rep.run.ok) rep.err = measure(rep.run.samples, ref, L);
    rep.run.samples.clear();
    std::printf("%-22s %-18s %-12s %10.0f ns/step  err %9.2e  (q %8.1e  v %8.1e  a %8.1e)%s%s\n",
                example.c_str(), rep.run.method.c_str(), rep.run.setting.c_str(),
                rep.run.ns_per_step, rep.err.max(), rep.err.q, rep.err.v, rep.err.a,
                rep.run.note.empty() ? "" : "  ", rep.run.note.c_str());
    std::fflush(stdout);
    reports_.push_back(std::move(rep));
  }

  BenchGrid g_;
  bool all_methods_;
  std::vector<Report> reports_;
};

}  // namespace
}  // namespace kinegen::bench

int main(int argc, char** argv) {
  using namespace kinegen::bench;
  std::string csv = "work_precision.csv";
  bool quick = false;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "--quick") {
      quick = true;
    } else if (arg == "-h" || arg == "--help") {
      std::printf("usage: bench_work_precision [CSV] [--quick]\n");
      return 0;
    } else {
      csv = arg;
    }
  }
  // t_k = k * 2^-9 (about 0.11 degree of crank per step): exact in double, and the reference
  // grid (every stride-th time) hits exactly the same times.
  BenchGrid g;
  g.stride = 128;
  g.grid.steps = quick ? 128 * 80 : 128 * 800;
  g.grid.t0 = 0;
  g.grid.t1 = g.grid.steps / 512.0;
  g.repetitions = quick ? 1 : 3;

  std::printf("kinegen work-precision benchmark\n");
  std::fflush(stdout);
  std::system("lscpu | grep -E '^(Model name|CPU\\(s\\)|Thread|Core)' | sed 's/^/machine: /'");
  std::printf(
      "grid: t = 0 .. %g s, %d steps (crank 1 rad/s: %.1f turns), best of %d; reference every "
      "%d-th step (%d times)\n",
      g.grid.t1, g.grid.steps, g.grid.t1 / (2 * M_PI), g.repetitions, g.stride,
      g.grid.steps / g.stride + 1);
  std::printf("reference: %s\n", reference_description().c_str());
  std::printf("%s\n", kErrorDefinition);
  std::printf(
      "a step = Newton position solve from the previous step's q, then velocity and "
      "acceleration\n");

  Bench bench(g, true);
  bench.example<kinegen::models::slider_crank>("slider_crank");
  bench.example<kinegen::models::slider_crank_lecture>("slider_crank_lecture");
  bench.example<kinegen::models::offset_slider_crank>("offset_slider_crank");
  bench.example<kinegen::models::four_bar>("four_bar");
  bench.example<kinegen::models::quick_return>("quick_return");
  bench.print_ratios();
  bench.write_csv(csv);
  std::printf("\nwrote %s\n", csv.c_str());
  return 0;
}
