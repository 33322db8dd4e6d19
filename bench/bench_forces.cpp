// Time of the generated kinetostatics next to the generated full step, on the same trajectory
// in one run (a crank turn in 0.1-degree steps), for each model with masses:
//
//   step          solve_step: position (Newton from the previous solution), velocity and
//                 acceleration through the blocks, keeping its factors (StepFactors)
//   reuse         solve_forces with the step's factors, at the stored states of a turn
//                 (phi_q, generalized_force, each block's transposed solve: nothing factored)
//   refactor      solve_forces without them (one LU per block again, with its condition);
//                 reuse and refactor alternate chunk by chunk, so that both see the same load
//   columns       force_columns: the efforts and reactions from the stored lambda
//   all           step, reuse and columns in a row, as a feedforward loop calls them
//
// The best of several chunks is reported. Prints a table; not a test.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include "best_of_chunks.hpp"
#include "closed_chain_masses.hpp"
#include "four_bar_balanced.hpp"
#include "planetary.hpp"
#include "press.hpp"
#include "slider_mass.hpp"
#include "table_press.hpp"

namespace {

constexpr int kChunk = 1000;
constexpr int kChunks = 72;
constexpr int kTurn = 3600;  // steps per turn (0.1 degree); kChunk * kChunks covers 20 turns
volatile double g_checksum = 0;

// Best time per call over the chunks (best_of_chunks.hpp).
template <class Chunk>
double best_ns(Chunk&& chunk) {
  return kinegen::bench::best_ns(kChunks, kChunk, chunk);
}

template <class M, class T>
void run(const char* name, double period) {
  const typename M::Params p{};
  const typename M::template BasicBlockOptions<T> o{};
  const T dt = T(period / kTurn);
  T q[M::nq], qd[M::nq], qdd[M::nq], lambda[M::nc], cols[M::num_force_columns];
  for (int k = 0; k < M::nq; ++k) q[k] = T(M::q0[k]);
  // The states of one turn, for timing solve_forces and force_columns on their own.
  struct State {
    T q[M::nq], qd[M::nq], qdd[M::nq], lambda[M::nc];
    typename M::template StepFactors<T> factors;
  };
  typename M::template StepFactors<T> factors;
  std::vector<State> turn(kTurn);
  const double ns_step = best_ns([&](int k0) {
    for (int k = k0; k < k0 + kChunk; ++k) {
      if (M::solve_step(q, T(k) * dt, p, qd, qdd, o, static_cast<T*>(nullptr), nullptr, &factors)
              .status != 0)
        return false;
      State& s = turn[k % kTurn];
      s.factors = factors;
      std::copy(q, q + M::nq, s.q);
      std::copy(qd, qd + M::nq, s.qd);
      std::copy(qdd, qdd + M::nq, s.qdd);
    }
    return true;
  });
  // Reuse and refactor alternate chunk by chunk, so that both see the same load.
  const auto forces_chunk = [&](int k0, bool reuse) {
    for (int k = k0; k < k0 + kChunk; ++k) {
      State& s = turn[k % kTurn];
      if (M::solve_forces(s.q, s.qd, s.qdd, T(k % kTurn) * dt, p, s.lambda, o,
                          reuse ? &s.factors : nullptr)
              .status != 0)
        return false;
    }
    return true;
  };
  double ns_reuse = 1e300, ns_refactor = 1e300;
  best_ns([&](int k0) {
    for (const bool reuse : {true, false}) {
      const auto start = std::chrono::steady_clock::now();
      if (!forces_chunk(k0, reuse)) return false;
      const double ns =
          std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start)
              .count() /
          kChunk;
      (reuse ? ns_reuse : ns_refactor) = std::min(reuse ? ns_reuse : ns_refactor, ns);
    }
    return true;
  });
  const double ns_columns = best_ns([&](int k0) {
    for (int k = k0; k < k0 + kChunk; ++k) {
      const State& s = turn[k % kTurn];
      M::force_columns(s.q, T(k % kTurn) * dt, p, s.lambda, cols);
      T sum = T(0);  // every column is used
      for (const T& c : cols) sum += c;
      g_checksum = g_checksum + double(sum);
    }
    return true;
  });
  for (int k = 0; k < M::nq; ++k) q[k] = T(M::q0[k]);
  const double ns_all = best_ns([&](int k0) {
    for (int k = k0; k < k0 + kChunk; ++k) {
      const T t = T(k) * dt;
      if (M::solve_step(q, t, p, qd, qdd, o, static_cast<T*>(nullptr), nullptr, &factors).status !=
          0)
        return false;
      if (M::solve_forces(q, qd, qdd, t, p, lambda, o, &factors).status != 0) return false;
      M::force_columns(q, t, p, lambda, cols);
      g_checksum = g_checksum + double(cols[0]);
    }
    return true;
  });
  std::printf("%-20s %-6s %5d %8.1f %8.1f %9.1f %8.1f %8.1f %7.2f\n", name,
              sizeof(T) == 4 ? "float" : "double", M::nq, ns_step, ns_reuse, ns_refactor,
              ns_columns, ns_all, ns_reuse / ns_step);
}

}  // namespace

int main() {
  std::printf("ns per call, best of %d chunks of %d calls (0.1 degree of crank per step)\n",
              kChunks, kChunk);
  std::printf("%-20s %-6s %5s %8s %8s %9s %8s %8s %7s\n", "model", "scalar", "nq", "step", "reuse",
              "refactor", "columns", "all", "r/step");
  run<kinegen::models::four_bar_balanced, double>("four_bar_balanced", 1.0);
  run<kinegen::models::four_bar_balanced, float>("four_bar_balanced", 1.0);
  run<kinegen::models::press, double>("press", 1.0);
  run<kinegen::models::press, float>("press", 1.0);
  run<kinegen::models::slider_mass, double>("slider_mass", 2 * M_PI / 3.0);
  run<kinegen::models::slider_mass, float>("slider_mass", 2 * M_PI / 3.0);
  run<kinegen::models::table_press, double>("table_press", 1.0);
  run<kinegen::models::table_press, float>("table_press", 1.0);
  run<kinegen::models::planetary, double>("planetary", 1.0);
  run<kinegen::models::planetary, float>("planetary", 1.0);
  run<kinegen::models::closed_chain_masses, double>("closed_chain_masses", 2 * M_PI);
  run<kinegen::models::closed_chain_masses, float>("closed_chain_masses", 2 * M_PI);
  return 0;
}
