// Shared pieces of the dynamics work-precision benchmark (bench_dynamics.cpp): the problems as
// numbers, one timed run's result, and the interface of the peers compiled on their own as
// C++17 (Simbody; the generated dynamics() of the committed headers). No kinegen headers here.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <string>
#include <vector>

namespace kinegen::bench::dynamics {

// One benchmark problem: which mechanism, its parameters (the file's values), the horizon.
// The free coordinate z is the absolute angle of one crank (the pendulum's rod, the press's
// crank, the N-four-bar's crank 0) in every problem.
struct Problem {
  std::string name;   // "pendulum", "press_flywheel", "n_four_bar"
  std::string label;  // as printed, e.g. "n_four_bar N=40, t1=0.25"
  int n = 0;          // N of the N-four-bar
  double t1 = 0;
  double z0 = 0, zd0 = 0;
  std::map<std::string, double> params;
  double param(const std::string& key) const { return params.at(key); }
};

// One timed run of one method at one setting: z and zd at t1.
struct Run {
  std::string method, setting;
  double seconds = NAN;  // best of the repetitions, the model built beforehand
  double z = NAN, zd = NAN;
  long steps = 0;  // the integrator's steps (where it says)
  bool ok = true;
  std::string note;  // why it failed
};

// The tolerances every adaptive method is swept over (rtol; Simbody: its accuracy).
inline const std::vector<double> kTolerances = {1e-4, 1e-6, 1e-8, 1e-10, 1e-12};

// The best wall time of up to `repetitions` calls of run() (false: a failure, NaN); a run
// longer than half a second runs once. Every peer is timed by it.
template <class F>
double best_seconds(int repetitions, F&& run) {
  double best = INFINITY;
  for (int rep = 0; rep < repetitions; ++rep) {
    const auto start = std::chrono::steady_clock::now();
    if (!run()) return NAN;
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    best = std::min(best, s);
    if (s > 0.5) break;
  }
  return best;
}

// Simbody (libsimbody-dev): a tree of Pin and Slider mobilizers closed by PointInPlane
// constraints, integrated by its Runge-Kutta-Merson integrator at each accuracy, with its
// constraint projection. None, with `skipped` saying why, where Simbody was not found.
std::vector<Run> run_simbody(const Problem& p, const std::vector<double>& tolerances,
                             int repetitions, std::string& skipped);

// The generated dynamics() (peer_generated_dynamics.cpp) of generated/<name>.hpp: the
// header's step_rk4() at each step size h (rounded to t1 / n), then CVODE on dynamics() at
// each tolerance as `kinegen simulate` sets it up. None, with `skipped` saying why, for a
// problem with no committed header.
std::vector<Run> run_generated(const Problem& p, const std::vector<double>& tolerances,
                               const std::vector<double>& steps, int repetitions,
                               std::string& skipped);

}  // namespace kinegen::bench::dynamics
