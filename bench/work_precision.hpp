// Shared pieces of the work-precision benchmark: the time grid, recorded samples, the error
// measure against the reference, and the interface of the peer solvers (SolveSpace, Simbody).
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

namespace kinegen::bench {

// The state a solver reached at one of the reference times.
struct Sample {
  Eigen::VectorXd q, qd, qdd;  // qd, qdd empty for position-only solvers
};

// One timed run of a method at one setting.
struct RunResult {
  std::string method, setting;
  double ns_per_step = NAN;  // best of the repetitions
  bool ok = true;
  std::string note;  // why it failed, or what it measured
  bool position_only = false;
  std::vector<Sample> samples;  // at the reference times
};

// t_k = t0 + k (t1 - t0) / steps, the same formula as codegen::TimeGrid (this header stays free
// of the generator so that peers can be compiled on their own, e.g. as C++17 for Simbody).
struct TimeGrid {
  double t0 = 0, t1 = 0;
  int steps = 0;
  double at(int k) const { return steps == 0 ? t0 : t0 + k * (t1 - t0) / steps; }
};

// The benchmark's grid: t_k = grid.at(k); the reference is computed at every `stride`-th time.
struct BenchGrid {
  TimeGrid grid;
  int stride = 128;
  int repetitions = 3;
  TimeGrid reference_grid() const { return {grid.t0, grid.t1, grid.steps / stride}; }
};

struct Errors {
  double q = NAN, v = NAN, a = NAN;
  double max() const {
    double m = q;
    if (!std::isnan(v)) m = std::max(m, v);
    if (!std::isnan(a)) m = std::max(m, a);
    return m;
  }
};

inline const char* kErrorDefinition =
    "error = max over the reference times of\n"
    "  e_q = max_k |q_k - qref_k| / s_k           (s_k = coordinate_scales[k]: x, y by their "
    "body's joints; 1 for phi)\n"
    "  e_v = max_k |qd_k - qdref_k| / s_k / V      (V = max over the run of max_k |qdref_k| / "
    "s_k)\n"
    "  e_a = max_k |qdd_k - qddref_k| / s_k / A    (A likewise for qddref)\n"
    "and the reported error is max(e_q, e_v, e_a) (position-only solvers: e_q).";

// Errors of `samples` against `ref` (same times) by the definition above.
inline Errors measure(const std::vector<Sample>& samples, const std::vector<Sample>& ref,
                      const std::vector<double>& scales) {
  Errors e;
  if (samples.size() != ref.size()) return e;
  auto scale = [&](int k) { return scales[k]; };
  double vmax = 0, amax = 0;
  for (const auto& r : ref)
    for (int k = 0; k < r.q.size(); ++k) {
      vmax = std::max(vmax, std::abs(r.qd[k]) / scale(k));
      amax = std::max(amax, std::abs(r.qdd[k]) / scale(k));
    }
  e.q = 0;
  const bool with_v = !samples.empty() && samples[0].qd.size() > 0;
  if (with_v) e.v = e.a = 0;
  for (std::size_t s = 0; s < samples.size(); ++s)
    for (int k = 0; k < ref[s].q.size(); ++k) {
      e.q = std::max(e.q, std::abs(samples[s].q[k] - ref[s].q[k]) / scale(k));
      if (with_v) {
        e.v = std::max(e.v, std::abs(samples[s].qd[k] - ref[s].qd[k]) / scale(k) / vmax);
        e.a = std::max(e.a, std::abs(samples[s].qdd[k] - ref[s].qdd[k]) / scale(k) / amax);
      }
    }
  return e;
}

// Runs `step(k, record)` for every k of the grid, `repetitions` times; returns the best time
// per step in ns. `step` returns false on failure (then the result is NaN).
template <class Step>
double time_steps(const BenchGrid& g, Step&& step, const std::function<void()>& reset) {
  double best = INFINITY;
  for (int rep = 0; rep < g.repetitions; ++rep) {
    reset();
    const auto start = std::chrono::steady_clock::now();
    for (int k = 0; k <= g.grid.steps; ++k)
      if (!step(k, k % g.stride == 0)) return NAN;
    const auto stop = std::chrono::steady_clock::now();
    best = std::min(
        best, std::chrono::duration<double, std::nano>(stop - start).count() / (g.grid.steps + 1));
  }
  return best;
}

// Peers: each returns its runs for the example, or none with `skipped` saying why.
std::vector<RunResult> run_solvespace(const std::string& example, const BenchGrid& g,
                                      std::string& skipped);
std::vector<RunResult> run_simbody(const std::string& example, const BenchGrid& g,
                                   std::string& skipped);

}  // namespace kinegen::bench
