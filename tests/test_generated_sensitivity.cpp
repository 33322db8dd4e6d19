// The generated headers' phi_p and solve_sensitivity against independent truths:
//  1. slider-cranks' closed forms for d(slider.x)/d(l), d(slider.x)/d(r), d(slider.x)/d(e);
//  2. central differences (Richardson-extrapolated) of the generated solve_position with the
//     parameter moved, on every example header;
//  3. the in-process sensitivities (analyze --sensitivity: dense LU of all of Phi_q), on every
//     example and on test mechanisms with larger, torn, split and rolled blocks;
//  4. float with default options, std::complex<double>, a singular block at a dead centre,
//     and --fold-params headers (no sensitivities).
// Errors are measured as in test_sensitivity.cpp: lengths in the mechanism's length scale,
// relative to max(1, the column's largest scaled |truth|).
#include <algorithm>
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <cstring>
#include <filesystem>
#include <kinegen/solver.hpp>
#include <string>
#include <type_traits>
#include <vector>

#include "closed_chain_4.hpp"
#include "four_bar.hpp"
#include "four_bar_folded.hpp"
#include "fourbar_chain_3_rolled_split.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "offset_slider_crank.hpp"
#include "quick_return.hpp"
#include "scissor_lift_3_split.hpp"
#include "slider_crank.hpp"
#include "slider_crank_folded.hpp"
#include "slider_crank_lecture.hpp"
#include "stephenson3.hpp"

namespace {

namespace cg = kinegen::codegen;
namespace fs = std::filesystem;
using namespace kinegen::models;
using Complex = std::complex<double>;

// Bounds, with the largest errors measured when they were set (g++ 12, x86-64): closed forms
// 2.2e-16 and the in-process solve 7.4e-16, both rounding (kappa eps); central differences
// with h = 1e-3 max(1, |p|) and one Richardson step (truncation ~ h^4, rounding ~ kappa eps /
// h) 5.5e-11; float 7.4e-8 absolute.
constexpr double kClosedForm = 1e-14;
constexpr double kInProcess = 1e-13;
constexpr double kDifferences = 1e-9;
constexpr double kFloat = 2e-6;

std::string source(const std::string& relative) {
  return (fs::path(KINEGEN_SOURCE_DIR) / relative).string();
}

// Params as an array of its members (it holds num_params doubles, nothing else).
template <class M>
std::array<double, M::num_params> values(const typename M::Params& p) {
  static_assert(sizeof(typename M::Params) == M::num_params * sizeof(double));
  std::array<double, M::num_params> v;
  std::memcpy(v.data(), &p, sizeof p);
  return v;
}
template <class M>
typename M::Params params(const std::array<double, M::num_params>& v) {
  typename M::Params p;
  std::memcpy(static_cast<void*>(&p), v.data(), sizeof p);  // trivially copyable
  return p;
}

template <class M>
double scale_of(int i) {
  return M::coordinate_kinds[i] == 1 ? 1.0 : M::length_scale;
}

// max over a column of |got - truth| / scale, relative to max(1, largest |truth| / scale).
template <class M>
double column_error(const double* got, const double* truth) {
  double size = 1, err = 0;
  for (int i = 0; i < M::nq; ++i) size = std::max(size, std::abs(truth[i]) / scale_of<M>(i));
  for (int i = 0; i < M::nq; ++i) err = std::max(err, std::abs(got[i] - truth[i]) / scale_of<M>(i));
  return err / size;
}

// The in-process analysis of `yaml` with every parameter's sensitivities.
std::vector<cg::StateRow> analyze(const std::string& yaml, const cg::TimeGrid& grid) {
  const auto model = cg::CompiledModel::from_file(yaml);
  std::vector<std::string> names;
  for (const auto& p : model->mechanism().parameters) names.push_back(p.name);
  const auto sens = cg::build_sensitivity(*model, names);
  cg::AnalysisOptions options;
  options.sensitivity = &sens;
  std::vector<cg::StateRow> rows;
  cg::run_analysis(
      *model, grid, [&](const cg::StateRow& r) { rows.push_back(r); }, options);
  return rows;
}

template <class M>
std::array<double, M::nq * M::num_params> sensitivity(const double* q, double t,
                                                      const typename M::Params& p) {
  std::array<double, M::nq * M::num_params> dq{};
  const auto report = M::solve_sensitivity(q, t, p, dq.data(), typename M::BlockOptions{});
  REQUIRE(report.status == 0);
  return dq;
}

// Generated against in-process on the rows of `yaml`; returns the largest error.
template <class M>
double agreement(const std::string& yaml) {
  static_assert(M::has_sensitivity);
  const auto rows = analyze(source(yaml), {0, 1, 8});
  REQUIRE(rows.size() == 9);
  double worst = 0;
  for (const auto& row : rows) {
    REQUIRE(row.dq_dp.rows() == M::nq);
    REQUIRE(row.dq_dp.cols() == M::num_params);
    const auto dq = sensitivity<M>(row.q.data(), row.t, typename M::Params{});
    for (int k = 0; k < M::num_params; ++k) {
      const double e = column_error<M>(dq.data() + k * M::nq, row.dq_dp.data() + k * M::nq);
      INFO(yaml << " t = " << row.t << " parameter " << k << ": error " << e);
      CHECK(e <= kInProcess);
      worst = std::max(worst, e);
    }
  }
  return worst;
}

// Generated against central differences of the generated position solve; returns the
// largest error.
template <class M>
double differences(const std::string& yaml) {
  const auto rows = analyze(source(yaml), {0, 6, 12});
  const auto p0 = values<M>(typename M::Params{});
  double worst = 0;
  for (const auto& row : rows) {
    const auto dq = sensitivity<M>(row.q.data(), row.t, typename M::Params{});
    for (int k = 0; k < M::num_params; ++k) {
      // q(p_k + s) from the solution at p (the same branch).
      const auto solve = [&](double s) {
        std::array<double, M::nq> q;
        std::copy(row.q.data(), row.q.data() + M::nq, q.begin());
        auto p = p0;
        p[k] += s;
        const auto report =
            M::solve_position(q.data(), row.t, params<M>(p), typename M::BlockOptions{});
        REQUIRE(report.status == 0);
        return q;
      };
      const double h = 1e-3 * std::max(1.0, std::abs(p0[k]));
      std::array<double, M::nq> truth;
      const auto qh1 = solve(h), qm1 = solve(-h), qh2 = solve(h / 2), qm2 = solve(-h / 2);
      for (int i = 0; i < M::nq; ++i) {
        const double d1 = (qh1[i] - qm1[i]) / (2 * h), d2 = (qh2[i] - qm2[i]) / h;
        truth[i] = (4 * d2 - d1) / 3;
      }
      const double e = column_error<M>(dq.data() + k * M::nq, truth.data());
      INFO(yaml << " t = " << row.t << " parameter " << k << ": error " << e);
      CHECK(e <= kDifferences);
      worst = std::max(worst, e);
    }
  }
  return worst;
}

}  // namespace

TEST_CASE("generated sensitivities match the slider-cranks' closed forms",
          "[sensitivity][generated]") {
  // offset_slider_crank: Params {r, l, e, omega}; the slider B is body 2's origin, q[6]:
  // x = r cos th + sqrt(l^2 - (e - r sin th)^2).
  using M = offset_slider_crank;
  static_assert(M::num_params == 4 && M::nq == 9);
  const M::Params p{};
  const double r = p.r, l = p.l, e = p.e;
  double worst = 0;
  for (const auto& row :
       analyze(source("examples/offset_slider_crank.yaml"), {0, 2 * std::acos(-1.0), 72})) {
    const double th = row.t, s = std::sin(th), c = std::cos(th);
    const double root = std::sqrt(l * l - (e - r * s) * (e - r * s));
    REQUIRE(std::abs(row.q[6] - (r * c + root)) <= 1e-13);
    const auto dq = sensitivity<M>(row.q.data(), th, p);
    const auto at = [&](int param, int coordinate) { return dq[param * M::nq + coordinate]; };
    const double truth[] = {c + (e - r * s) * s / root,  // d x / d r
                            l / root,                    // d x / d l
                            -(e - r * s) / root};        // d x / d e
    INFO("t = " << th);
    for (int k = 0; k < 3; ++k) {
      CHECK(std::abs(at(k, 6) - truth[k]) <= kClosedForm);
      worst = std::max(worst, std::abs(at(k, 6) - truth[k]));
    }
    CHECK(std::abs(at(3, 2) - th) <= kClosedForm * std::max(1.0, th));  // d(crank.phi)/d(omega)
    CHECK(std::abs(at(2, 7) - 1) <= kClosedForm);  // the slider line moves with e
  }
  // slider_crank (crank length 1, Params {l, omega}): the slider is the rod's origin, q[3].
  for (const auto& row : analyze(source("examples/slider_crank.yaml"), {0, 6, 24})) {
    const double s = std::sin(row.t), root = std::sqrt(4.0 - s * s);
    const auto dq = sensitivity<slider_crank>(row.q.data(), row.t, slider_crank::Params{});
    CHECK(std::abs(dq[3] - 2.0 / root) <= kClosedForm);
    worst = std::max(worst, std::abs(dq[3] - 2.0 / root));
  }
}

TEST_CASE("generated sensitivities equal central differences of the generated position solve",
          "[sensitivity][generated]") {
  std::vector<std::string> examples;
  for (const auto& f : fs::directory_iterator(source("examples")))
    if (f.path().extension() == ".yaml") examples.push_back(f.path().filename().string());
  // Every example has its header here: a new example must be added.
  CHECK(examples.size() == 5);
  double worst = 0;
  worst = std::max(worst, differences<four_bar>("examples/four_bar.yaml"));
  worst = std::max(worst, differences<offset_slider_crank>("examples/offset_slider_crank.yaml"));
  worst = std::max(worst, differences<quick_return>("examples/quick_return.yaml"));
  worst = std::max(worst, differences<slider_crank>("examples/slider_crank.yaml"));
  worst = std::max(worst, differences<slider_crank_lecture>("examples/slider_crank_lecture.yaml"));
}

TEST_CASE("generated sensitivities agree with the in-process ones", "[sensitivity][generated]") {
  double worst = 0;
  worst = std::max(worst, agreement<four_bar>("examples/four_bar.yaml"));
  worst = std::max(worst, agreement<offset_slider_crank>("examples/offset_slider_crank.yaml"));
  worst = std::max(worst, agreement<quick_return>("examples/quick_return.yaml"));
  worst = std::max(worst, agreement<slider_crank>("examples/slider_crank.yaml"));
  worst = std::max(worst, agreement<slider_crank_lecture>("examples/slider_crank_lecture.yaml"));
  // A 5 x 5 block, a torn 6 x 6 one split into parts, rolled and split phi_p, 11 parameters.
  worst = std::max(worst, agreement<closed_chain_4>("tests/mechanisms/closed_chain_4.yaml"));
  worst = std::max(worst, agreement<scissor_lift_3_split>("tests/mechanisms/scissor_lift_3.yaml"));
  worst = std::max(
      worst, agreement<fourbar_chain_3_rolled_split>("tests/mechanisms/fourbar_chain_3.yaml"));
  worst = std::max(worst, agreement<stephenson3>("tests/mechanisms/stephenson3.yaml"));
}

TEST_CASE("generated sensitivities in float and std::complex<double>", "[sensitivity][generated]") {
  using M = offset_slider_crank;
  const M::Params p{};
  const double r = p.r, l = p.l, e = p.e;
  double worst = 0;
  for (const auto& row : analyze(source("examples/offset_slider_crank.yaml"), {0, 6, 24})) {
    // float: position and sensitivities with the default options of float.
    std::array<float, M::nq> qf;
    for (int i = 0; i < M::nq; ++i) qf[i] = static_cast<float>(row.q[i]);
    const float tf = static_cast<float>(row.t);
    const M::BasicBlockOptions<float> of;
    REQUIRE(M::solve_position(qf.data(), tf, p, of).status == 0);
    std::array<float, M::nq * M::num_params> dqf;
    REQUIRE(M::solve_sensitivity(qf.data(), tf, p, dqf.data(), of).status == 0);
    const double th = tf, s = std::sin(th), c = std::cos(th);
    const double root = std::sqrt(l * l - (e - r * s) * (e - r * s));
    const double truth[] = {c + (e - r * s) * s / root, l / root, -(e - r * s) / root};
    for (int k = 0; k < 3; ++k) {
      INFO("t = " << row.t << " parameter " << k << ": " << dqf[k * M::nq + 6] << " vs "
                  << truth[k]);
      CHECK(std::abs(dqf[k * M::nq + 6] - truth[k]) <= kFloat);
      worst = std::max(worst, std::abs(dqf[k * M::nq + 6] - truth[k]));
    }
    // std::complex<double> on the real axis: the double result, to rounding.
    std::array<Complex, M::nq> qc;
    for (int i = 0; i < M::nq; ++i) qc[i] = row.q[i];
    std::array<Complex, M::nq * M::num_params> dqc;
    REQUIRE(
        M::solve_sensitivity(qc.data(), Complex(row.t), p, dqc.data(), M::BlockOptions{}).status ==
        0);
    const auto dq = sensitivity<M>(row.q.data(), row.t, p);
    for (int k = 0; k < M::nq * M::num_params; ++k) {
      CHECK(std::abs(dqc[k].real() - dq[k]) <= 1e-15 * std::max(1.0, std::abs(dq[k])));
      CHECK(dqc[k].imag() == 0);
    }
  }
}

TEST_CASE("generated solve_sensitivity reports a singular block at a dead centre",
          "[sensitivity][generated]") {
  // four_bar with the rocker shortened to c = b - (d - a) = 1.5: at th = 0 the coupler and the
  // rocker lie along the ground line (A = (1, 0), B = (4.5, 0), O4 = (3, 0)), a toggle. The
  // block of the coupler's and the rocker's angles then has a zero row (the pin's x equation
  // does not move with either angle), and the position below is exact.
  using M = four_bar;
  M::Params p;
  p.c = 1.5;
  const double q[M::nq] = {0, 0, 0, 1, 0, 0, 3, 0, 0};
  double res[M::nc];
  M::phi(q, 0.0, p, res);
  for (double v : res) REQUIRE(v == 0);
  REQUIRE(M::coordinate_block[5] == M::coordinate_block[8]);
  std::array<double, M::nq * M::num_params> dq;
  const auto report = M::solve_sensitivity(q, 0.0, p, dq.data(), M::BlockOptions{});
  CHECK(report.status == 2);
  CHECK(report.block == M::coordinate_block[5]);
  // Work space of the caller's gives the same verdict; a NaN position is status 3.
  std::array<double, M::sensitivity_work_size> work;
  const auto with_work = M::solve_sensitivity(q, 0.0, p, dq.data(), M::BlockOptions{}, work.data());
  CHECK(with_work.status == 2);
  CHECK(with_work.block == report.block);
  double bad[M::nq];
  std::copy(q, q + M::nq, bad);
  bad[5] = std::nan("");
  CHECK(M::solve_sensitivity(bad, 0.0, p, dq.data(), M::BlockOptions{}).status == 3);
  // Near the toggle (t = 0.2 on the same linkage) the block is regular again.
  std::array<double, M::nq> q2;
  std::copy(q, q + M::nq, q2.begin());
  q2[5] = 0.05;
  q2[8] = 0.3;
  REQUIRE(M::solve_position(q2.data(), 0.2, p, M::BlockOptions{}).status == 0);
  CHECK(M::solve_sensitivity(q2.data(), 0.2, p, dq.data(), M::BlockOptions{}).status == 0);
}

TEST_CASE("--fold-params headers have no sensitivities", "[sensitivity][generated]") {
  static_assert(!four_bar_folded::has_sensitivity && !slider_crank_folded::has_sensitivity);
  static_assert(four_bar_folded::num_params == four_bar::num_params);
  static_assert(four_bar::has_sensitivity && four_bar::num_params == 7);
  SUCCEED();
}

TEST_CASE("Solver::sensitivity is the generated solve_sensitivity", "[sensitivity][generated]") {
  using M = four_bar;
  M::Params p;
  p.b = 3.4;  // the solver's own params, not the defaults
  kinegen::Solver<M> solver(p);
  static_assert(kinegen::Solver<M>::kSensitivity &&
                !kinegen::Solver<four_bar_folded>::kSensitivity);
  auto q = solver.initial_estimate();
  REQUIRE(solver.position(q, 0.3));
  kinegen::Solver<M>::SensitivityMatrix dq_dp;
  REQUIRE(solver.sensitivity(q, 0.3, dq_dp));
  std::array<double, M::nq * M::num_params> direct;
  REQUIRE(M::solve_sensitivity(q.data(), 0.3, p, direct.data(), M::BlockOptions{}).status == 0);
  for (int k = 0; k < M::nq * M::num_params; ++k) CHECK(dq_dp.data()[k] == direct[k]);
  // At the toggle of the dead-centre test: kSingular, and no stale values.
  M::Params toggle;
  toggle.c = 1.5;
  kinegen::Solver<M> at_toggle(toggle);
  kinegen::Solver<M>::Vector qt;
  qt << 0, 0, 0, 1, 0, 0, 3, 0, 0;
  const auto r = at_toggle.sensitivity(qt, 0.0, dq_dp);
  CHECK(r.status == kinegen::Status::kSingular);
  CHECK(std::isnan(dq_dp(0, 0)));
}
