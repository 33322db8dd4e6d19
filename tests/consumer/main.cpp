// Solves the generated slider-crank at one time and prints the slider's position.
#include <cstdio>
#include <kinegen/solver.hpp>

#include "slider_crank.hpp"

int main() {
  using Model = kinegen::models::slider_crank;
  kinegen::Solver<Model> solver;
  auto q = solver.initial_estimate();
  const double t = 0.5;
  if (!solver.position(q, t)) return 1;
  std::printf("slider x at t = 0.5: %.9f\n", q[3]);  // rod origin = slider, x_rod is q[3]
  return 0;
}
