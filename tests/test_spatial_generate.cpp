// `kinegen generate` on spatial files (docs/format.md, Spatial mechanisms): the spatial
// slider-crank's header, stepped by the runtime's Solver, against the closed form
// x(theta) = sqrt(0.09 - (0.1 - 0.08 sin theta)^2 - (0.12 + 0.08 cos theta)^2) and against
// `kinegen analyze`; a first solve at t0 = 0.3 on the assembly the q0 pose shows (the
// revolute_angle's row also vanishes on the mirrored one); the branch check in the generated
// solve; float against double; the complex step of phi against phi_q for both spatial headers.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <cstdlib>
#include <kinegen/block_solver.hpp>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "spatial_all_types.hpp"
#include "spatial_slider_crank.hpp"
#include "support/csv_columns.hpp"
#include "support/files.hpp"
#include "support/run_command.hpp"

namespace {

using Crank = kinegen::models::spatial_slider_crank;
using AllTypes = kinegen::models::spatial_all_types;
constexpr double kOmega = 6;

std::string mechanism(const std::string& name) {
  return std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/" + name + ".yaml";
}

// The slider's x at crank angle th (the closed form), and the crank pin's y and z.
double slider_x(double th) {
  const double y = 0.1 - 0.08 * std::sin(th), z = 0.12 + 0.08 * std::cos(th);
  return std::sqrt(0.09 - y * y - z * z);
}

// Where the crank pin (0, 0, 0.08 in the crank's frame) is: r + A(p) s.
template <class T>
std::array<T, 3> pin(const T* q) {
  const T e0 = q[3], e1 = q[4], e2 = q[5], e3 = q[6];
  const T s = T(0.08);
  // The third column of A(p) (homogeneous form) times 0.08.
  return {q[0] + s * 2 * (e1 * e3 + e0 * e2), q[1] + s * 2 * (e2 * e3 - e0 * e1),
          q[2] + s * (e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3)};
}

// Indices of the slider's x and the bodies' Euler parameters.
constexpr int kSliderX = 14;

TEST_CASE("spatial generate: the slider-crank's Solver against the closed form",
          "[spatial][generate]") {
  for (const double t0 : {0.0, 0.3}) {
    kinegen::Solver<Crank> solver;
    auto q = solver.initial_estimate();
    decltype(q) qd = decltype(q)::Zero(), qdd = decltype(q)::Zero();
    double worst_x = 0, worst_pin = 0, worst_unit = 0;
    for (int k = 0; k <= 40; ++k) {
      const double t = t0 + k * (1.3 - t0) / 40;
      const auto r = solver.step(t, q, qd, qdd);
      INFO("t0 " << t0 << ", t " << t << ": status " << static_cast<int>(r.status));
      REQUIRE(r);
      const double th = kOmega * t;
      worst_x = std::max(worst_x, std::abs(q[kSliderX] - slider_x(th)));
      const auto p = pin(q.data());
      worst_pin = std::max({worst_pin, std::abs(p[0]), std::abs(p[1] - (0.1 - 0.08 * std::sin(th))),
                            std::abs(p[2] - (0.12 + 0.08 * std::cos(th)))});
      for (int b = 0; b < 3; ++b) {
        double pp = 0;
        for (int e = 3; e < 7; ++e) pp += q[7 * b + e] * q[7 * b + e];
        worst_unit = std::max(worst_unit, std::abs(pp - 1));
      }
    }
    CHECK(worst_x < 1e-12 * 0.3);
    CHECK(worst_pin < 1e-12 * 0.3);
    CHECK(worst_unit < 1e-13);
    WARN("t0 " << t0 << ": x " << worst_x << ", pin " << worst_pin << ", |p|^2 - 1 " << worst_unit);
  }
}

TEST_CASE("spatial generate: a first solve at t0 = 0.3 lands on the q0 pose's assembly",
          "[spatial][generate]") {
  // The crank at 1.8 rad, not at 1.8 - pi (the revolute_angle's row vanishes on both).
  kinegen::Solver<Crank> solver;
  auto q = solver.initial_estimate();
  REQUIRE(solver.position(q, 0.3));
  const auto p = pin(q.data());
  CHECK(std::abs(p[1] - (0.1 - 0.08 * std::sin(1.8))) < 1e-13);
  CHECK(std::abs(p[2] - (0.12 + 0.08 * std::cos(1.8))) < 1e-13);
  CHECK(std::abs(q[kSliderX] - slider_x(1.8)) < 1e-13);
  // The header's q0 has unit Euler parameters.
  for (int b = 0; b < 3; ++b) {
    double pp = 0;
    for (int e = 3; e < 7; ++e) pp += Crank::q0[7 * b + e] * Crank::q0[7 * b + e];
    CHECK(std::abs(pp - 1) < 1e-15);
  }
}

TEST_CASE("spatial generate: the generated solve refuses the mirrored assembly",
          "[spatial][generate]") {
  // The pose at crank angle 1.8 + pi solves Phi at t = 0.3 too (sin(1.8 - theta) = 0): the
  // generated solve converges there at once and must fail its branch check, status 6.
  kinegen::Solver<Crank> solver;
  auto mirrored = solver.initial_estimate();
  REQUIRE(solver.position(mirrored, (1.8 + M_PI) / kOmega));
  double phi[Crank::nc];
  Crank::phi(mirrored.data(), 0.3, Crank::Params{}, phi);
  for (double v : phi) REQUIRE(std::abs(v) < 1e-12);
  auto q = mirrored;
  const auto report = Crank::solve_position(q.data(), 0.3, Crank::Params{}, Crank::BlockOptions{});
  CHECK(report.status == 6);
  auto qd = q, qdd = q;
  const auto step = Crank::solve_step(q.data(), 0.3, Crank::Params{}, qd.data(), qdd.data(),
                                      Crank::BlockOptions{});
  CHECK(step.status == 6);
  // A Solver past its first solve, given the mirrored pose, refuses it too.
  kinegen::Solver<Crank> later;
  auto first = later.initial_estimate();
  REQUIRE(later.position(first, 0.3));
  auto at = mirrored;
  CHECK_FALSE(later.position(at, 0.3));
}

TEST_CASE("spatial generate: the header's step agrees with analyze", "[spatial][generate]") {
  const auto r =
      kinegen::test::run_command({KINEGEN_EXE, "analyze", mechanism("spatial_slider_crank"), "--t0",
                                  "0.3", "--t1", "1.3", "--steps", "40"});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  auto c = kinegen::test::csv_columns(r.out);
  const auto& times = c["t"];
  REQUIRE(times.size() == 41);
  kinegen::Solver<Crank> solver;
  auto q = solver.initial_estimate();
  decltype(q) qd = decltype(q)::Zero(), qdd = decltype(q)::Zero();
  const char* bodies[] = {"crank", "rod", "slider"};
  const char* names[] = {".x", ".y", ".z", ".e0", ".e1", ".e2", ".e3"};
  const char* rates[] = {".vx", ".vy", ".vz"};
  const char* accelerations[] = {".ax", ".ay", ".az"};
  double worst_q = 0, worst_v = 0, worst_a = 0;
  for (std::size_t k = 0; k < times.size(); ++k) {
    REQUIRE(solver.step(times[k], q, qd, qdd));
    for (int b = 0; b < 3; ++b) {
      for (int i = 0; i < 7; ++i)
        worst_q =
            std::max(worst_q, std::abs(q[7 * b + i] - c[bodies[b] + std::string(names[i])][k]));
      for (int i = 0; i < 3; ++i) {
        worst_v =
            std::max(worst_v, std::abs(qd[7 * b + i] - c[bodies[b] + std::string(rates[i])][k]));
        worst_a = std::max(
            worst_a, std::abs(qdd[7 * b + i] - c[bodies[b] + std::string(accelerations[i])][k]));
      }
    }
  }
  // Every step is the same block program in both, but analyze's first solve continues the
  // drivers on its dense Phi_q and the header's on its block factors: a coordinate that is 0
  // (the crank's e2 and e3) is exactly 0 in the header and noise of 1e-49 in analyze, which
  // the later steps carry, so the rows agree to rounding rather than bit for bit.
  CHECK(worst_q < 1e-14);
  CHECK(worst_v < 1e-14 * kOmega);
  CHECK(worst_a < 1e-14 * kOmega * kOmega);
  WARN("header against analyze: q " << worst_q << ", v " << worst_v << ", a " << worst_a);
}

TEST_CASE("spatial generate: float within 1e-5 of double", "[spatial][generate]") {
  kinegen::Solver<Crank> solver;
  kinegen::Solver<Crank, float> single;
  auto q = solver.initial_estimate();
  auto qf = single.initial_estimate();
  decltype(q) qd = decltype(q)::Zero(), qdd = decltype(q)::Zero();
  decltype(qf) qdf = decltype(qf)::Zero(), qddf = decltype(qf)::Zero();
  double worst = 0;
  for (int k = 0; k <= 40; ++k) {
    const double t = 0.3 + k * 0.025;
    REQUIRE(solver.step(t, q, qd, qdd));
    REQUIRE(single.step(static_cast<float>(t), qf, qdf, qddf));
    for (int i = 0; i < Crank::nq; ++i)
      worst = std::max(worst, std::abs(q[i] - static_cast<double>(qf[i])));
  }
  CHECK(worst < 1e-5);
  WARN("float against double: " << worst);
}

// Phi_q against the complex step of phi (h = 1e-30: no cancellation), at a pose off the
// assembly (every entry counts, not only where Phi = 0).
template <class Model>
void check_complex_step(const typename Model::Params& params, double t) {
  using C = std::complex<double>;
  std::array<double, Model::nq> q;
  for (int k = 0; k < Model::nq; ++k) q[k] = Model::q0[k] + 0.01 * std::sin(k + 1.0);
  std::array<double, Model::jac_nnz> jac;
  Model::phi_q(q.data(), t, params, jac.data());
  std::vector<double> dense(Model::nc * Model::nq, 0.0);
  for (int e = 0; e < Model::jac_nnz; ++e)
    dense[Model::jac_rows[e] * Model::nq + Model::jac_cols[e]] = jac[e];
  double worst = 0, size = 0;
  for (int k = 0; k < Model::nq; ++k) {
    std::array<C, Model::nq> qc;
    for (int i = 0; i < Model::nq; ++i) qc[i] = q[i];
    qc[k] += C(0, 1e-30);
    std::array<C, Model::nc> phi;
    Model::phi(qc.data(), C(t), params, phi.data());
    for (int r = 0; r < Model::nc; ++r) {
      worst = std::max(worst, std::abs(phi[r].imag() / 1e-30 - dense[r * Model::nq + k]));
      size = std::max(size, std::abs(dense[r * Model::nq + k]));
    }
  }
  CHECK(size > 0.1);
  CHECK(worst < 1e-13 * size);
}

TEST_CASE("spatial generate: phi_q against the complex step of phi", "[spatial][generate]") {
  check_complex_step<Crank>(Crank::Params{}, 0.3);
  check_complex_step<AllTypes>(AllTypes::Params{}, 0.7);
  STATIC_REQUIRE(AllTypes::nq == 21);
  STATIC_REQUIRE(Crank::nq == 21);
  STATIC_REQUIRE(Crank::nc == 21);
}

TEST_CASE("spatial generate: the header's sensitivity to omega against the closed form",
          "[spatial][generate]") {
  // x(omega t): dx/domega = x'(theta) t.
  kinegen::Solver<Crank> solver;
  auto q = solver.initial_estimate();
  const double t = 0.5, th = kOmega * t;
  REQUIRE(solver.position(q, t));
  STATIC_REQUIRE(Crank::num_params == 1);
  double dq_dp[Crank::nq];
  REQUIRE(
      Crank::solve_sensitivity(q.data(), t, Crank::Params{}, dq_dp, Crank::BlockOptions{}).status ==
      0);
  const double y = 0.1 - 0.08 * std::sin(th), z = 0.12 + 0.08 * std::cos(th);
  const double du = -2 * (y * -0.08 * std::cos(th) + z * -0.08 * std::sin(th));
  CHECK(std::abs(dq_dp[kSliderX] - du / (2 * slider_x(th)) * t) < 1e-12);
}

TEST_CASE("spatial generate: a model named like a spatial header's member is refused",
          "[spatial][generate]") {
  // A struct continued_rows cannot have the member continued_rows (the drivers' rows).
  std::string text = kinegen::test::read_text(mechanism("spatial_slider_crank"));
  const std::string name = "name: spatial_slider_crank";
  text.replace(text.find(name), name.size(), "name: continued_rows");
  const auto dir = kinegen::test::scratch_dir("spatial_generate", "member_name");
  kinegen::test::write_text(dir / "crank.yaml", text);
  const auto r = kinegen::test::run_command(
      {KINEGEN_EXE, "generate", (dir / "crank.yaml").string(), "-o", (dir / "out").string()});
  INFO(r.err);
  CHECK(r.exit_code == 2);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK(r.err.find("continued_rows") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(dir / "out" / "continued_rows.hpp"));
}

}  // namespace
