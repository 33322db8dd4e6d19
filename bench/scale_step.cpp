// Time per full analysis step of one generated model, for scripts/bench_scale.sh. Compiled
// once per model with -DKINEGEN_SCALE_HEADER='"path/<name>.hpp"' -DKINEGEN_SCALE_MODEL=<name>
// and one of:
//   (nothing)                      the generated block solver's full step (solve_step) with
//                                  the Taylor predictor, as kinegen::Solver<Model>::step;
//   -DKINEGEN_SCALE_DYNAMIC        dense Newton (one LU of all of Phi_q, run-time sized);
//   -DKINEGEN_SCALE_FUNCTIONS_ONLY one evaluation of phi, phi_q, nu and gamma (double).
// Prints one line of `key value` pairs (nq, ns_per_step or ns_per_evaluation, ...). A step is
// position, velocity and acceleration at t_k = k dt; the best of a few repetitions. Not a test.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <vector>

#include KINEGEN_SCALE_HEADER
#include <kinegen/motion.hpp>

#ifdef KINEGEN_SCALE_FUNCTIONS_ONLY
// Only the generated functions, for double: what compiling the generated code costs without
// the solver, and one evaluation of Phi, Phi_q, nu and gamma (a lower bound for any step).
int main(int argc, char** argv) {
  using Model = kinegen::models::KINEGEN_SCALE_MODEL;
  const int evaluations = argc > 1 ? std::atoi(argv[1]) : 1000;
  const int repetitions = argc > 2 ? std::atoi(argv[2]) : 3;
  std::vector<double> q(Model::q0.begin(), Model::q0.end()), qd(Model::nq, 0.1);
  std::vector<double> out(Model::nc + Model::jac_nnz + 1);
  const Model::Params p{};
  double best = 1e300, checksum = 0;
  for (int rep = 0; rep < repetitions; ++rep) {
    const auto start = std::chrono::steady_clock::now();
    for (int k = 0; k < evaluations; ++k) {
      const double t = 1e-3 * k;
      // q and qd count as changed: nothing may be hoisted out of the loop.
      asm volatile("" : : "r"(q.data()), "r"(qd.data()) : "memory");
      Model::phi(q.data(), t, p, out.data());
      checksum += out[0];
      Model::phi_q(q.data(), t, p, out.data());
      checksum += out[0];
      Model::nu(q.data(), t, p, out.data());
      checksum += out[0];
      Model::gamma(q.data(), qd.data(), t, p, out.data());
      checksum += out[0];
    }
    const auto stop = std::chrono::steady_clock::now();
    best = std::min(best,
                    std::chrono::duration<double, std::nano>(stop - start).count() / evaluations);
  }
  std::printf("nq %d ns_per_evaluation %.0f jac_nnz %d checksum %.6g\n", Model::nq, best,
              Model::jac_nnz, checksum);
  return std::isfinite(checksum) ? 0 : 1;
}
#elif defined(KINEGEN_SCALE_DYNAMIC)
#include <kinegen/solver.hpp>
// The dense baseline: the runtime's Newton with one LU of the whole Phi_q, run-time sized.
int main(int argc, char** argv) {
  using Model = kinegen::models::KINEGEN_SCALE_MODEL;
  using SolverT =
      kinegen::BasicSolver<kinegen::GeneratedSystem<Model>, Eigen::Dynamic, Eigen::Dynamic>;
  const int steps = argc > 1 ? std::atoi(argv[1]) : 300;
  const int repetitions = argc > 2 ? std::atoi(argv[2]) : 3;
  const double dt = argc > 3 ? std::atof(argv[3]) : 0.01;
  SolverT solver{kinegen::GeneratedSystem<Model>()};
  Eigen::VectorXd q0(Model::nq);
  for (int k = 0; k < Model::nq; ++k) q0[k] = Model::q0[k];
  Eigen::VectorXd q = q0, qd = q0, qdd = q0;
  double best = 1e300, checksum = 0;
  long iterations = 0;
  for (int rep = 0; rep < repetitions; ++rep) {
    q = q0;
    iterations = 0;
    const auto start = std::chrono::steady_clock::now();
    for (int k = 0; k < steps; ++k) {
      const double t = k * dt;
      const auto r = solver.position(q, t);
      if (!r) {
        std::fprintf(stderr, "error: position failed at t = %g: %s\n", t, r.message());
        return 1;
      }
      iterations += r.iterations;
      solver.velocity(q, t, qd);
      solver.acceleration(q, qd, t, qdd);
    }
    const auto stop = std::chrono::steady_clock::now();
    best = std::min(best, std::chrono::duration<double, std::nano>(stop - start).count() / steps);
    checksum += q.sum() + qd.sum() + qdd.sum();
  }
  std::printf("nq %d ns_per_step %.0f iterations %.2f steps %d checksum %.6g\n", Model::nq, best,
              static_cast<double>(iterations) / steps, steps, checksum);
  return std::isfinite(checksum) ? 0 : 1;
}
#else
// The generated block solver's full step with the Taylor predictor, as kinegen::Solver<Model>
// ::step runs it; called directly because Solver<Model> also holds the dense fallback's
// fixed-size nq x nq workspace, which Eigen refuses beyond about 128 coordinates.
int main(int argc, char** argv) {
  using Model = kinegen::models::KINEGEN_SCALE_MODEL;
  static_assert(Model::has_block_solver, "the header has no block solver");
  const int steps = argc > 1 ? std::atoi(argv[1]) : 300;
  const int repetitions = argc > 2 ? std::atoi(argv[2]) : 3;
  const double dt = argc > 3 ? std::atof(argv[3]) : 0.01;
  const Model::Params p{};
  const Model::BlockOptions options{};
  std::vector<double> q(Model::nq), qd(Model::nq), qdd(Model::nq), qdd_before(Model::nq);
  // The sin/cos cache, as Solver<Model> keeps it (NaN: empty).
  std::vector<double> trig(Model::trig_cache_size);
  double best = 1e300, checksum = 0;
  long iterations = 0;
  for (int rep = 0; rep < repetitions; ++rep) {
    std::copy(Model::q0.begin(), Model::q0.end(), q.begin());
    std::fill(trig.begin(), trig.end(), std::numeric_limits<double>::quiet_NaN());
    iterations = 0;
    const auto start = std::chrono::steady_clock::now();
    for (int k = 0; k < steps; ++k) {
      const double t = k * dt;
      if (k > 0) {  // the predictor of Solver<Model>::step
        const kinegen::TaylorPredictor<double> predict(dt, dt, k > 1);
        for (int j : Model::newton_coordinates) {
          const double a = qdd[j];
          q[j] = predict(q[j], qd[j], qdd[j], qdd_before[j]);
          qdd_before[j] = a;
        }
      }
      const auto r = Model::solve_step(q.data(), t, p, qd.data(), qdd.data(), options, trig.data());
      if (r.status != 0) {
        std::fprintf(stderr, "error: step failed at t = %g in block %d (status %d)\n", t, r.block,
                     r.status);
        return 1;
      }
      iterations += r.iterations;
    }
    const auto stop = std::chrono::steady_clock::now();
    best = std::min(best, std::chrono::duration<double, std::nano>(stop - start).count() / steps);
    for (int j = 0; j < Model::nq; ++j) checksum += q[j] + qd[j] + qdd[j];
  }
  std::printf("nq %d ns_per_step %.0f iterations %.2f steps %d checksum %.6g\n", Model::nq, best,
              static_cast<double>(iterations) / steps, steps, checksum);
  return std::isfinite(checksum) ? 0 : 1;
}
#endif
