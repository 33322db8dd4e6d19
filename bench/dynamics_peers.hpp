// Shared pieces of the dynamics work-precision benchmark (bench_dynamics.cpp): the problems as
// numbers, one timed run's result, and the interface of the peers compiled on their own as
// C++17 (Simbody; the generated dynamics() from branch `gen` later). No kinegen headers here.
#pragma once

#include <cmath>
#include <map>
#include <string>
#include <vector>

namespace kinegen::bench::dynamics {

// One benchmark problem: which mechanism, its parameters (the file's values), the horizon.
// The free coordinate z is the absolute angle of one crank (the pendulum's rod, the press's
// crank, the N-four-bar's crank 0) in every problem.
struct Problem {
  std::string name;     // "pendulum", "press_flywheel", "n_four_bar"
  std::string label;    // as printed, e.g. "n_four_bar N=40, t1=0.25"
  int n = 0;            // N of the N-four-bar
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
  long steps = 0;        // the integrator's steps (where it says)
  bool ok = true;
  std::string note;      // why it failed
};

// The tolerances every adaptive method is swept over (rtol; Simbody: its accuracy).
inline const std::vector<double> kTolerances = {1e-4, 1e-6, 1e-8, 1e-10, 1e-12};

// Simbody (libsimbody-dev): a tree of Pin and Slider mobilizers closed by PointInPlane
// constraints, integrated by its Runge-Kutta-Merson integrator at each accuracy, with its
// constraint projection. None, with `skipped` saying why, where Simbody was not found.
std::vector<Run> run_simbody(const Problem& p, const std::vector<double>& tolerances,
                             int repetitions, std::string& skipped);

}  // namespace kinegen::bench::dynamics
