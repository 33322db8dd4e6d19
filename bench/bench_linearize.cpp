// The exact A, B of `kinegen linearize` against the finite differences a user would write
// (central differences of the dynamics: 2 (2 nf + nu) evaluations of zdd), in process: the
// time of one exact evaluation (the state and the tangent) against the differences', and the
// differences' error against the exact Jacobians (which agree with a long-double complex step
// to 3e-16: tests/test_linearize.cpp), relative to the largest entry of [A B] or of zdd.
// Prints numbers; not a test. Run: build/bench/bench_linearize
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/linearize.hpp"

namespace kc = kinegen::codegen;

namespace {

using Clock = std::chrono::steady_clock;
double sink = 0;

struct Case {
  const char* file;
  std::vector<double> z, zd, u;
};

// Best of `rounds` rounds of `n` calls, in microseconds per call.
template <class F>
double micros(int rounds, int n, F&& f) {
  double best = 1e300;
  for (int r = 0; r < rounds; ++r) {
    const auto start = Clock::now();
    for (int k = 0; k < n; ++k) f();
    best = std::min(best, std::chrono::duration<double, std::micro>(Clock::now() - start).count() / n);
  }
  return best;
}

void run(const Case& c) {
  kc::BuildOptions build;
  build.free_as_state = true;
  const auto model = kc::CompiledModel::from_file(
      std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/" + c.file + ".yaml", {}, build);
  const kc::ForceModel forces = kc::derive_forces(*model);
  kc::Linearizer lin(*model, forces, 0);
  kc::OperatingPoint p = lin.initial();
  for (std::size_t k = 0; k < c.z.size(); ++k) p.z[k] = c.z[k];
  for (std::size_t k = 0; k < c.zd.size(); ++k) p.zd[k] = c.zd[k];
  for (std::size_t k = 0; k < c.u.size(); ++k) p.u[k] = c.u[k];
  const int nf = lin.nf(), nu = lin.nu(), n = 2 * nf + nu;
  kc::MotionState s;
  Eigen::MatrixXd dz, dzd, du;
  const double exact = micros(5, 200, [&] {
    lin.evaluate(p, s, &dz, &dzd, &du);
    sink += dz(0, 0);
  });
  const double state = micros(5, 200, [&] {
    lin.evaluate(p, s);
    sink += s.zdd[0];
  });
  Eigen::MatrixXd j(nf, n), fd(nf, n);
  j << dz, dzd, du;
  const Eigen::VectorXd scales = lin.scales();
  const double differences = micros(5, 200, [&] {
    for (int col = 0; col < n; ++col) {
      const double h = 1e-5 * (col < 2 * nf ? scales[col % nf] : 1.0);
      Eigen::VectorXd side[2];
      for (int k = 0; k < 2; ++k) {
        kc::OperatingPoint x = p;
        const double step = k == 0 ? h : -h;
        if (col < nf) x.z[col] += step;
        else if (col < 2 * nf) x.zd[col - nf] += step;
        else x.u[col - 2 * nf] += step;
        lin.evaluate(x, s);
        side[k] = s.zdd;
      }
      fd.col(col) = (side[0] - side[1]) / (2 * h);
    }
    sink += fd(0, 0);
  });
  lin.evaluate(p, s);
  const double scale = std::max(j.cwiseAbs().maxCoeff(), s.zdd.cwiseAbs().maxCoeff());
  std::printf("%-16s %2d %2d %8.2f %8.2f %8.2f %4d %8.2f %6.1fx %6.1fx %8.1e\n", c.file, nf, nu,
              state, exact, exact - state, 2 * n, differences, differences / exact,
              differences / (exact - state), (fd - j).cwiseAbs().maxCoeff() / scale);
}

}  // namespace

int main() {
  std::printf("in-process (the analysis' evaluator), microseconds per call, best of 5 x 200:\n"
              "zdd alone; zdd and the exact Jacobians; the Jacobians alone (the difference);\n"
              "central differences (2 (2 nf + nu) evaluations of zdd); their time over the exact\n"
              "one's, and over the Jacobians' alone; their error relative to max |[A B]|, |zdd|\n");
  std::printf("%-16s %2s %2s %8s %8s %8s %4s %8s %7s %7s %8s\n", "mechanism", "nf", "nu", "zdd",
              "exact", "tangent", "n", "differ.", "ratio", "ratio_t", "error");
  run({"pendulum", {-1.2}, {0.5}, {}});
  run({"four_bar_damped", {0.7}, {-3.0}, {}});
  run({"four_bar_spring", {4.2}, {1.0}, {}});
  run({"cart_pole", {0.3, 1.2}, {-0.7, 2.1}, {3.5}});
  run({"n_four_bar_4", {0.9}, {-1.0}, {}});
  return sink == 12345 ? 1 : 0;
}
