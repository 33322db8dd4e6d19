// The condition estimate of the runtime's dense and sparse Newton paths, written once.
#pragma once

#include <cmath>
#include <type_traits>

namespace kinegen::detail {

// Hager's (Higham's) estimate of 1 / (|A|_1 |A^-1|_1) from A's factors (ws.lu, which solves by
// A and, through transpose(), by A^T) and |A|_1 (norm_a), for the dense path (solver.hpp) and
// the sparse one (sparse_solver.hpp). Written out rather than Eigen's rcond(), because GCC warns
// inside Eigen's version for fixed sizes and the sparse LU has none; no allocation.
template <class WS>
double hager_reciprocal_condition(WS& ws, double norm_a, int n) {
  using Scalar = typename std::decay_t<decltype(ws.est_x)>::Scalar;
  if (!(norm_a > 0)) return 0.0;
  ws.est_x.setConstant(Scalar(1) / Scalar(n));
  double estimate = 0;
  int last = -1;
  for (int iter = 0; iter < 5; ++iter) {
    ws.est_y = ws.lu.solve(ws.est_x);  // A^-1 x
    const double norm_y = static_cast<double>(ws.est_y.cwiseAbs().sum());
    if (iter > 0 && norm_y <= estimate) break;
    estimate = norm_y;
    for (int k = 0; k < n; ++k) ws.est_x[k] = ws.est_y[k] >= Scalar(0) ? Scalar(1) : Scalar(-1);
    ws.est_z = ws.lu.transpose().solve(ws.est_x);  // A^-T sign(y)
    int j = 0;
    ws.est_z.cwiseAbs().maxCoeff(&j);
    if (j == last) break;
    last = j;
    ws.est_x.setZero();
    ws.est_x[j] = Scalar(1);
  }
  if (!std::isfinite(estimate) || !(estimate > 0)) return 0.0;
  return 1.0 / (norm_a * estimate);
}

}  // namespace kinegen::detail
