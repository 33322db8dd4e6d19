// Embedding a generated model: the four-bar's header from generated/ and the runtime's Solver,
// run over one crank turn. No heap allocation after the solver is built, no exceptions.
//
//   g++ -std=c++17 -O2 -I generated -I runtime/include -I /usr/include/eigen3
//       examples/embed_four_bar.cpp -o embed_four_bar
#include <cmath>
#include <cstdio>

#include "four_bar.hpp"
#include <kinegen/solver.hpp>

int main() {
  using Model = kinegen::models::four_bar;
  Model::Params params;  // defaults from four_bar.yaml; change any member for a design study
  params.omega = 2.0;    // crank speed [rad/s]
  kinegen::Solver<Model> solver(params);

  auto q = solver.initial_estimate();
  kinegen::Solver<Model>::Vector qd, qdd;
  const double period = 2 * M_PI / params.omega;
  const int steps = 12;
  std::printf("%8s %12s %12s %12s %6s\n", "t", "coupler.phi", "rocker.phi", "rocker.alpha", "iters");
  for (int k = 0; k <= steps; ++k) {
    const double t = period * k / steps;
    const kinegen::Result r = solver.position(q, t);  // Newton from the previous solution
    if (!r) {
      std::fprintf(stderr, "error: position failed at t = %g: %s\n", t, r.message());
      return 1;
    }
    solver.velocity(q, t, qd);
    solver.acceleration(q, qd, t, qdd);
    std::printf("%8.4f %12.8f %12.8f %12.6f %6d\n", t, q[5], q[8], qdd[8], r.iterations);
  }
  return 0;
}
