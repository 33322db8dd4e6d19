// The generated kinetostatics (solve_forces, force_columns) against independent
// truths: virtual power on a slider-crank whose only mass is the slider, the closed
// form of an accelerating crank under gravity (also with Params changed at run time),
// the in-process ForceSolver of `analyze --forces` over a turn of the balanced four-bar, float
// with default options, std::complex<double>, --fold-params against Params, and a toggle
// position reported as a failure.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include "crank_gravity.hpp"
#include "four_bar_balanced.hpp"
#include "four_bar_balanced_folded.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "slider_driven.hpp"
#include "slider_mass.hpp"
#include "slider_mass_position.hpp"
#include "slider_mass_velocity.hpp"

namespace {

namespace km = kinegen::models;
namespace kc = kinegen::codegen;

// One step of the generated model at t from the q in `s` (the previous solution), then the
// force columns; false when either solve fails.
template <class T>
struct RealOf {
  using type = T;
};
template <class T>
struct RealOf<std::complex<T>> {
  using type = T;
};

template <class M, class T>
struct Generated {
  typename M::Params p{};
  T q[M::nq], qd[M::nq], qdd[M::nq], lambda[M::nc], columns[M::num_force_columns];
  // The defaults of T's precision.
  typename M::template BasicBlockOptions<typename RealOf<T>::type> options{};

  Generated() {
    for (int k = 0; k < M::nq; ++k) q[k] = T(M::q0[k]);
  }
  bool step(T t) {
    if (M::solve_step(q, t, p, qd, qdd, options).status != 0) return false;
    if (M::solve_forces(q, qd, qdd, t, p, lambda, options).status != 0) return false;
    M::force_columns(q, t, p, lambda, columns);
    return true;
  }
};

constexpr double kPi = 3.14159265358979323846;
constexpr double kEps = std::numeric_limits<double>::epsilon();

}  // namespace

TEST_CASE("generated forces: virtual power on a slider-crank with only a slider mass",
          "[forces][generated]") {
  using M = km::slider_mass;
  static_assert(M::has_forces && M::num_force_columns == 1 + 4 * 3);
  CHECK(std::string(M::force_column_names[0]) == "motor.effort");
  Generated<M, double> g;
  const double r = g.p.r, l = g.p.l, m = g.p.ms, omega = g.p.omega;
  double worst = 0, scale = 0;
  for (int k = 0; k <= 720; ++k) {
    const double t = 2 * kPi * k / 720;
    REQUIRE(g.step(t));
    // theta(t) and x(theta) in closed form (slider_mass.yaml).
    const double th = omega * t + 0.4 * std::sin(2 * t), thd = omega + 0.8 * std::cos(2 * t),
                 thdd = -1.6 * std::sin(2 * t);
    const double c = std::cos(th), s = std::sin(th), w = std::sqrt(l * l - r * r * s * s);
    const double x1 = -r * s - r * r * s * c / w;
    const double x2 =
        -r * c - r * r * (c * c - s * s) / w - std::pow(r, 4) * s * s * c * c / (w * w * w);
    const double xd = x1 * thd, xdd = x2 * thd * thd + x1 * thdd;
    REQUIRE(g.q[6] == Approx(r * c + w).epsilon(1e-12));
    const double power = m * xdd * xd;
    worst = std::max(worst, std::abs(g.columns[0] * thd - power));
    scale = std::max(scale, std::abs(power));
  }
  INFO("largest |effort * theta_dot - m xdd xd| " << worst << " of " << scale);
  CHECK(scale > 10);
  CHECK(worst <= 32 * kEps * scale);
}

TEST_CASE("generated forces: an accelerating crank under gravity, Params read at run time",
          "[forces][generated]") {
  using M = km::crank_gravity;
  for (const auto& [mass, grav, rc] :
       {std::array<double, 3>{1.5, 9.81, 0.3}, std::array<double, 3>{2.0, 3.0, 0.25}}) {
    Generated<M, double> g;
    g.p.m = mass;
    g.p.g = grav;
    g.p.rc = rc;
    const double j = g.p.J;
    double worst = 0, scale = 0;
    for (int k = 0; k <= 300; ++k) {
      const double t = 3.0 * k / 300;
      REQUIRE(g.step(t));
      const double phi = 0.2 * t + 0.75 * t * t, w = 0.2 + 1.5 * t, alpha = 1.5;
      const double torque = (j + mass * rc * rc) * alpha + mass * grav * rc * std::cos(phi);
      // a_com of the point rc along the crank; the pin's force on the crank is m a_com - m g.
      const double ax = rc * (-std::sin(phi) * alpha - std::cos(phi) * w * w),
                   ay = rc * (std::cos(phi) * alpha - std::sin(phi) * w * w);
      const double truth[4] = {torque, mass * ax, mass * ay + mass * grav, 0.0};
      for (int c = 0; c < 4; ++c) {
        worst = std::max(worst, std::abs(g.columns[c] - truth[c]));
        scale = std::max(scale, std::abs(truth[c]));
      }
    }
    INFO("m " << mass << " g " << grav << " rc " << rc << ": largest error " << worst << " of "
              << scale);
    CHECK(worst <= 16 * kEps * scale);
  }
}

namespace {

// The in-process columns of `analyze --forces` on the balanced four-bar over a turn.
struct Reference {
  std::vector<double> t;
  std::vector<Eigen::VectorXd> q, qd, qdd;
  std::vector<std::vector<double>> columns;
};

const Reference& four_bar_reference() {
  static const Reference ref = [] {
    Reference r;
    const auto model = kc::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                    "/examples/forces/four_bar_balanced.yaml");
    const kc::ForceModel forces = kc::forces_for_analysis(*model);
    kc::ForceSolver solver(*model, forces);
    kc::run_analysis(*model, {0, 1, 360}, [&](const kc::StateRow& row) {
      std::vector<double> cols;
      REQUIRE(solver.solve(row.t, row.q, row.qd, row.qdd, cols));
      r.t.push_back(row.t);
      r.q.push_back(row.q);
      r.qd.push_back(row.qd);
      r.qdd.push_back(row.qdd);
      r.columns.push_back(cols);
    });
    REQUIRE(r.t.size() == 361);
    REQUIRE(kc::force_columns(model->mechanism()).size() ==
            static_cast<std::size_t>(km::four_bar_balanced::num_force_columns));
    return r;
  }();
  return ref;
}

double largest(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}

}  // namespace

TEST_CASE("generated forces equal the in-process ForceSolver on the balanced four-bar",
          "[forces][generated]") {
  using M = km::four_bar_balanced;
  const Reference& ref = four_bar_reference();
  const auto model = kc::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                  "/examples/forces/four_bar_balanced.yaml");
  const auto names = kc::force_columns(model->mechanism());
  for (int c = 0; c < M::num_force_columns; ++c) CHECK(names[c] == M::force_column_names[c]);
  const M::Params p{};
  double same_input = 0, own_step = 0;
  Generated<M, double> g;
  for (std::size_t k = 0; k < ref.t.size(); ++k) {
    // The in-process row's q, qd, qdd: only the force arithmetic differs.
    double lambda[M::nc], cols[M::num_force_columns];
    const auto report = M::solve_forces(ref.q[k].data(), ref.qd[k].data(), ref.qdd[k].data(),
                                        ref.t[k], p, lambda, M::BlockOptions{});
    REQUIRE(report.status == 0);
    M::force_columns(ref.q[k].data(), ref.t[k], p, lambda, cols);
    // The generated step's own kinematics: the kinematics' rounding on top.
    REQUIRE(g.step(ref.t[k]));
    const double scale = largest(ref.columns[k]);
    for (int c = 0; c < M::num_force_columns; ++c) {
      same_input = std::max(same_input, std::abs(cols[c] - ref.columns[k][c]) / scale);
      own_step = std::max(own_step, std::abs(g.columns[c] - ref.columns[k][c]) / scale);
    }
  }
  INFO("largest difference relative to the row's largest force: same q, qd, qdd "
       << same_input << ", generated step " << own_step);
  CHECK(same_input <= 16 * kEps);
  CHECK(own_step <= 1e-12);
}

TEST_CASE("generated forces in float (default options) and std::complex<double>",
          "[forces][generated]") {
  using M = km::four_bar_balanced;
  const Reference& ref = four_bar_reference();
  Generated<M, float> f;
  Generated<M, std::complex<double>> z;
  double worst_float = 0, worst_complex = 0, imag = 0;
  for (std::size_t k = 0; k < ref.t.size(); ++k) {
    REQUIRE(f.step(static_cast<float>(ref.t[k])));
    REQUIRE(z.step(ref.t[k]));
    const double scale = largest(ref.columns[k]);
    for (int c = 0; c < M::num_force_columns; ++c) {
      worst_float = std::max(worst_float, std::abs(f.columns[c] - ref.columns[k][c]) / scale);
      worst_complex =
          std::max(worst_complex, std::abs(z.columns[c].real() - ref.columns[k][c]) / scale);
      imag = std::max(imag, std::abs(z.columns[c].imag()));
    }
  }
  INFO("float " << worst_float << ", complex " << worst_complex << " of the row's largest force");
  CHECK(worst_float <= 1e-5);
  CHECK(worst_complex <= 1e-13);
  CHECK(imag == 0);
}

TEST_CASE("generated forces: a toggle position fails with its block, never a value",
          "[forces][generated]") {
  using M = km::slider_driven;
  const M::Params p{};
  const double zero[M::nq] = {};
  double lambda[M::nc];
  // Crank and rod in line, slider at r + l: the crank's angle is not fixed to first order.
  const double toggle[M::nq] = {0, 0, 0, p.r, 0, 0, p.r + p.l, 0, 0};
  double phi[M::nc];
  M::phi(toggle, 2.0, p, phi);  // the toggle time
  for (double v : phi) REQUIRE(v == 0);
  const auto report = M::solve_forces(toggle, zero, zero, 2.0, p, lambda, M::BlockOptions{});
  CHECK(report.status == 2);
  CHECK(report.block >= 0);
  CHECK(report.block < M::num_blocks);
  // Approaching the toggle (t = 2) along the motion: the reported condition grows.
  Generated<M, double> g;
  double last_rcond = 1;
  for (double t = 0; t < 1.995; t += 0.01) {
    REQUIRE(M::solve_step(g.q, t, g.p, g.qd, g.qdd, g.options).status == 0);
    const auto r = M::solve_forces(g.q, g.qd, g.qdd, t, g.p, g.lambda, g.options);
    REQUIRE(r.status == 0);
    if (t < 1.5) continue;
    INFO("t " << t << " rcond " << r.rcond);
    CHECK(r.rcond < last_rcond);
    last_rcond = r.rcond;
  }
  CHECK(last_rcond < 0.01);
}

TEST_CASE("generated forces with --fold-params equal the run-time Params header",
          "[forces][generated]") {
  using M = km::four_bar_balanced;
  using F = km::four_bar_balanced_folded;
  static_assert(F::has_forces && F::num_force_columns == M::num_force_columns);
  const Reference& ref = four_bar_reference();
  double worst = 0;
  for (std::size_t k = 0; k < ref.t.size(); ++k) {
    double lm[M::nc], lf[F::nc], cm[M::num_force_columns], cf[F::num_force_columns];
    REQUIRE(M::solve_forces(ref.q[k].data(), ref.qd[k].data(), ref.qdd[k].data(), ref.t[k],
                            M::Params{}, lm, M::BlockOptions{})
                .status == 0);
    REQUIRE(F::solve_forces(ref.q[k].data(), ref.qd[k].data(), ref.qdd[k].data(), ref.t[k],
                            F::Params{}, lf, F::BlockOptions{})
                .status == 0);
    M::force_columns(ref.q[k].data(), ref.t[k], M::Params{}, lm, cm);
    F::force_columns(ref.q[k].data(), ref.t[k], F::Params{}, lf, cf);
    const double scale = largest(ref.columns[k]);
    for (int c = 0; c < M::num_force_columns; ++c)
      worst = std::max(worst, std::abs(cm[c] - cf[c]) / scale);
  }
  INFO("largest difference folded / Params, relative to the row's largest force: " << worst);
  CHECK(worst <= 16 * kEps);
}

namespace {
template <class M, class = void>
struct HasForces : std::false_type {};
template <class M>
struct HasForces<M, std::void_t<decltype(M::has_forces)>> : std::true_type {};
template <class M, class = void>
struct HasAcceleration : std::false_type {};
template <class M>
struct HasAcceleration<M, std::void_t<decltype(&M::template solve_acceleration<double, double>)>>
    : std::true_type {};
}  // namespace

TEST_CASE("generate --outputs position or velocity: no force functions, which need qdd",
          "[forces][generated]") {
  // The same mechanism with a mass: the full header has them, the partial ones do not.
  CHECK(HasForces<km::slider_mass>::value);
  CHECK(HasAcceleration<km::slider_mass>::value);
  CHECK_FALSE(HasForces<km::slider_mass_position>::value);
  CHECK_FALSE(HasForces<km::slider_mass_velocity>::value);
  CHECK_FALSE(HasAcceleration<km::slider_mass_velocity>::value);
  CHECK(km::slider_mass_position::nq == km::slider_mass::nq);
}

TEST_CASE(
    "near a toggle the in-process and the generated force solves call the same positions "
    "singular",
    "[forces][generated]") {
  // The slider-driven slider-crank at crank angle theta, assembled in closed form; theta -> 0
  // is the toggle (crank and rod in line). The scaled condition grows like 1 / theta.
  using M = km::slider_driven;
  const M::Params p{};
  const auto model = kc::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                  "/tests/mechanisms/slider_driven.yaml");
  const auto forces = kc::derive_forces(*model);
  kc::ForceSolver solver(*model, forces);
  const double zero[M::nq] = {};
  int both_fail = 0, both_pass = 0;
  for (int k = 1; k <= 15; ++k) {
    const double theta = std::pow(10.0, -k);
    const double phi = -std::asin(p.r * std::sin(theta) / p.l);
    const double q[M::nq] = {0,
                             0,
                             theta,
                             p.r * std::cos(theta),
                             p.r * std::sin(theta),
                             phi,
                             p.r * std::cos(theta) + p.l * std::cos(phi),
                             0,
                             0};
    double lambda[M::nc];
    const auto report = M::solve_forces(q, zero, zero, 0.0, p, lambda, M::BlockOptions{});
    std::vector<double> columns;
    const bool in_process =
        solver.solve(0.0, Eigen::Map<const Eigen::VectorXd>(q, M::nq), Eigen::VectorXd::Zero(M::nq),
                     Eigen::VectorXd::Zero(M::nq), columns);
    INFO("theta " << theta << ": generated rcond " << report.rcond << " status " << report.status
                  << ", in-process condition " << solver.condition());
    // The two estimates differ (per block, whole matrix) by a small factor; away from the
    // limit by more than that, the verdicts agree.
    const double rcond = 1 / solver.condition(), limit = kc::force_min_rcond<double>();
    if (rcond > 0.1 * limit && rcond < 10 * limit) continue;
    CHECK(in_process == (report.status == 0));
    both_fail += !in_process && report.status != 0;
    both_pass += in_process && report.status == 0;
  }
  // Both sides of the limit were seen, including positions between the old in-process limit
  // (eps) and min_rcond.
  CHECK(both_pass >= 5);
  CHECK(both_fail >= 2);
}

// ---- The step's factors reused (StepFactors): solve_forces straight after solve_step at the
// same t factors nothing again (kernels/block_linear.hpp, _block_transposed_reusing).
namespace {

// No sin/cos cache (solve_step's T* argument, which nullptr alone cannot deduce).
template <class T>
T* no_trig() {
  return nullptr;
}

// The largest |Phi_q^T lambda - Q| of a coordinate against the largest |Phi_q^T| |lambda| + |Q|
// of any: an independent check of a solve of Phi_q^T lambda = Q (0 for an exact one, a few eps
// after rounding).
template <class M>
double transposed_residual(const double* q, const double* qd, const double* qdd, double t,
                           const typename M::Params& p, const double* lambda) {
  double jac[M::jac_nnz], b[M::nq], sum[M::nq], size[M::nq];
  M::phi_q(q, t, p, jac);
  M::generalized_force(q, qd, qdd, t, p, b);
  for (int c = 0; c < M::nq; ++c) {
    sum[c] = -b[c];
    size[c] = std::abs(b[c]);
  }
  for (int e = 0; e < M::jac_nnz; ++e) {
    sum[M::jac_cols[e]] += jac[e] * lambda[M::jac_rows[e]];
    size[M::jac_cols[e]] += std::abs(jac[e] * lambda[M::jac_rows[e]]);
  }
  double worst = 0, scale = 0;
  for (int c = 0; c < M::nq; ++c) {
    worst = std::max(worst, std::abs(sum[c]));
    scale = std::max(scale, size[c]);
  }
  return worst / scale;
}

// Over `steps` steps of [0, t1]: solve_step keeping its factors, then solve_forces with them and
// without (every block factored again). Returns the largest difference of lambda relative to
// the row's largest |lambda|, in units of eps; checks each solve's residual and the condition.
template <class M>
double reuse_against_refactor(double t1, int steps, int* kept_blocks) {
  Generated<M, double> g;
  typename M::template StepFactors<double> factors;
  double worst = 0, residual = 0;
  // Blocks with factors (K x K or torn; a 1 x 1 block's coefficient is an entry of Phi_q).
  int factored = 0;
  *kept_blocks = 0;
  for (int k = 0; k < M::num_blocks; ++k) {
    *kept_blocks += M::step_factored[k];
    factored += M::block_tears[k] > 0 || M::block_begin[k + 1] - M::block_begin[k] > 1;
  }
  for (int k = 0; k <= steps; ++k) {
    const double t = t1 * k / steps;
    const auto step =
        M::solve_step(g.q, t, g.p, g.qd, g.qdd, g.options, no_trig<double>(), nullptr, &factors);
    REQUIRE(step.status == 0);
    CHECK(factors.rcond == step.rcond);
    double reused[M::nc], again[M::nc];
    const auto r1 = M::solve_forces(g.q, g.qd, g.qdd, t, g.p, reused, g.options, &factors);
    const auto r2 = M::solve_forces(g.q, g.qd, g.qdd, t, g.p, again, g.options);
    REQUIRE(r1.status == 0);
    REQUIRE(r2.status == 0);
    // The step's condition, not measured again; with the blocks the step did not keep
    // factored here, the smallest with theirs.
    if (*kept_blocks == factored) CHECK(r1.rcond == step.rcond);
    CHECK(r1.rcond == std::min(step.rcond, r1.rcond));
    double scale = 0;
    for (double v : again) scale = std::max(scale, std::abs(v));
    for (int r = 0; r < M::nc; ++r)
      worst = std::max(worst, std::abs(reused[r] - again[r]) / (scale * kEps));
    residual = std::max(residual, transposed_residual<M>(g.q, g.qd, g.qdd, t, g.p, reused));
  }
  INFO("largest |Phi_q^T lambda - Q| relative, reused factors: " << residual);
  CHECK(residual <= 64 * kEps);
  return worst;
}

}  // namespace

#include "closed_chain_masses.hpp"
#include "closed_chain_masses_split.hpp"
#include "planetary.hpp"
#include "press.hpp"
#include "scissor_lift_masses.hpp"
#include "scissor_lift_masses_rolled.hpp"
#include "table_press.hpp"

TEST_CASE("generated forces with the step's factors equal those factored again",
          "[forces][generated][reuse]") {
  int kept = 0;
  const double press = reuse_against_refactor<km::press>(1.0, 400, &kept);
  CHECK(kept == 0);  // 1 x 1 blocks only: each coefficient is an entry of Phi_q
  const double balanced = reuse_against_refactor<km::four_bar_balanced>(1.0, 400, &kept);
  CHECK(kept > 0);
  const double table = reuse_against_refactor<km::table_press>(1.0, 400, &kept);
  const double planetary = reuse_against_refactor<km::planetary>(1.0, 400, &kept);
  // One torn block (2 tears, 3 coordinates assigned): the transposed solve through the tears.
  static_assert(km::closed_chain_masses::block_tears[km::closed_chain_masses::num_blocks - 1] == 2);
  const double torn = reuse_against_refactor<km::closed_chain_masses>(2 * kPi, 400, &kept);
  CHECK(kept == 1);
  // Split into parts: solve_step's parts keep the factors.
  const double split = reuse_against_refactor<km::closed_chain_masses_split>(2 * kPi, 400, &kept);
  CHECK(kept == 1);
  // Three torn stages; rolled (--roll-min 2), the repeated blocks keep their factors inside
  // their functions, and solve_forces factors those again (6 x 6 LU, checked as without).
  const double lift = reuse_against_refactor<km::scissor_lift_masses>(2 * kPi, 200, &kept);
  CHECK(kept == 3);
  const double rolled = reuse_against_refactor<km::scissor_lift_masses_rolled>(2 * kPi, 200, &kept);
  CHECK(kept < 3);
  INFO("largest |reused - refactored| / max |lambda| in eps: press "
       << press << ", four_bar_balanced " << balanced << ", table_press " << table << ", planetary "
       << planetary << ", closed_chain_masses (torn) " << torn << ", split " << split
       << ", scissor_lift_masses " << lift << ", rolled " << rolled);
  CHECK(std::max({press, balanced, table, planetary, torn, split, lift, rolled}) <= 16);
}

TEST_CASE("generated forces with the step's factors in float and std::complex<double>",
          "[forces][generated][reuse]") {
  using M = km::closed_chain_masses;  // the torn block
  Generated<M, double> d;
  Generated<M, float> f;
  Generated<M, std::complex<double>> z;
  M::StepFactors<double> fd;
  M::StepFactors<float> ff;
  M::StepFactors<std::complex<double>> fz;
  double worst_float = 0, worst_complex = 0, imag = 0;
  for (int k = 0; k <= 200; ++k) {
    const double t = 2 * kPi * k / 200;
    REQUIRE(M::solve_step(d.q, t, d.p, d.qd, d.qdd, d.options, no_trig<double>(), nullptr, &fd)
                .status == 0);
    REQUIRE(
        M::solve_step(f.q, float(t), f.p, f.qd, f.qdd, f.options, no_trig<float>(), nullptr, &ff)
            .status == 0);
    REQUIRE(M::solve_step(z.q, std::complex<double>(t), z.p, z.qd, z.qdd, z.options,
                          no_trig<std::complex<double>>(), nullptr, &fz)
                .status == 0);
    REQUIRE(M::solve_forces(d.q, d.qd, d.qdd, t, d.p, d.lambda, d.options, &fd).status == 0);
    REQUIRE(M::solve_forces(f.q, f.qd, f.qdd, float(t), f.p, f.lambda, f.options, &ff).status == 0);
    REQUIRE(
        M::solve_forces(z.q, z.qd, z.qdd, std::complex<double>(t), z.p, z.lambda, z.options, &fz)
            .status == 0);
    double scale = 0;
    for (double v : d.lambda) scale = std::max(scale, std::abs(v));
    for (int r = 0; r < M::nc; ++r) {
      worst_float = std::max(worst_float, std::abs(f.lambda[r] - d.lambda[r]) / scale);
      worst_complex = std::max(worst_complex, std::abs(z.lambda[r].real() - d.lambda[r]) / scale);
      imag = std::max(imag, std::abs(z.lambda[r].imag()));
    }
  }
  INFO("float " << worst_float << ", complex " << worst_complex << " of the largest |lambda|");
  CHECK(worst_float <= 1e-4);
  CHECK(worst_complex <= 1e-13);
  CHECK(imag == 0);
}

TEST_CASE("generated forces with the step's factors near a toggle: the step's condition",
          "[forces][generated][reuse]") {
  using M = km::slider_driven;
  Generated<M, double> g;
  M::StepFactors<double> factors;
  double last_rcond = 1;
  for (double t = 0; t < 1.995; t += 0.01) {
    const auto step =
        M::solve_step(g.q, t, g.p, g.qd, g.qdd, g.options, no_trig<double>(), nullptr, &factors);
    REQUIRE(step.status == 0);
    const auto r = M::solve_forces(g.q, g.qd, g.qdd, t, g.p, g.lambda, g.options, &factors);
    REQUIRE(r.status == 0);
    CHECK(r.rcond == step.rcond);
    if (t < 1.5) continue;
    INFO("t " << t << " rcond " << r.rcond);
    CHECK(r.rcond < last_rcond);
    last_rcond = r.rcond;
  }
  CHECK(last_rcond < 0.01);
  // A condition limit above the step's: every block is factored again and checked, and the
  // verdict is the refactored one's (the block that fails, never a value).
  auto strict = g.options;
  strict.min_rcond = 2 * last_rcond;
  double lambda[M::nc];
  const auto again = M::solve_forces(g.q, g.qd, g.qdd, 1.99, g.p, lambda, strict);
  const auto reused = M::solve_forces(g.q, g.qd, g.qdd, 1.99, g.p, g.lambda, strict, &factors);
  CHECK(again.status == 2);
  CHECK(reused.status == again.status);
  CHECK(reused.block == again.block);
  // At the toggle the step fails, leaves rcond 0, and the factors are not used.
  const double toggle[M::nq] = {0, 0, 0, g.p.r, 0, 0, g.p.r + g.p.l, 0, 0}, zero[M::nq] = {};
  double q[M::nq], qd[M::nq], qdd[M::nq];
  std::copy(toggle, toggle + M::nq, q);
  CHECK(
      M::solve_step(q, 2.0, g.p, qd, qdd, g.options, no_trig<double>(), nullptr, &factors).status !=
      0);
  CHECK(factors.rcond == 0);
  const auto at = M::solve_forces(toggle, zero, zero, 2.0, g.p, lambda, g.options, &factors);
  CHECK(at.status == 2);
  CHECK(at.block >= 0);
}

#include "kinegen/block_solver.hpp"

TEST_CASE("kinegen::Solver: forces after step() reuse its factors, and only at its state",
          "[forces][generated][reuse]") {
  using M = km::closed_chain_masses;
  static_assert(kinegen::Solver<M>::kForces);
  kinegen::Solver<M> solver;
  kinegen::Solver<M>::Vector q = solver.initial_estimate(), qd, qdd, q0, qd0, qdd0;
  kinegen::Solver<M>::LambdaVector lambda, again;
  kinegen::Solver<M>::ForceColumns columns;
  double worst = 0, before = -1;
  for (int k = 0; k <= 200; ++k) {
    const double t = 2 * kPi * k / 200;
    REQUIRE(solver.step(t, q, qd, qdd));
    REQUIRE(solver.forces(q, qd, qdd, t, lambda));
    REQUIRE(M::solve_forces(q.data(), qd.data(), qdd.data(), t, M::Params{}, again.data(),
                            M::BlockOptions{})
                .status == 0);
    worst = std::max(worst, (lambda - again).cwiseAbs().maxCoeff() / again.cwiseAbs().maxCoeff());
    REQUIRE(solver.force_columns(q, qd, qdd, t, columns));
    if (k > 0) {
      // The previous state is not the last step's: factored again, bit for bit the refactoring.
      REQUIRE(solver.forces(q0, qd0, qdd0, before, lambda));
      REQUIRE(M::solve_forces(q0.data(), qd0.data(), qdd0.data(), before, M::Params{}, again.data(),
                              M::BlockOptions{})
                  .status == 0);
      CHECK(lambda == again);
    }
    q0 = q, qd0 = qd, qdd0 = qdd, before = t;
  }
  INFO("largest |Solver::forces - refactored| / max |lambda|: " << worst);
  CHECK(worst <= 64 * kEps);
  // Float: the same solve in float's precision.
  kinegen::Solver<M, float> f;
  kinegen::Solver<M, float>::Vector qf = f.initial_estimate(), qdf, qddf;
  kinegen::Solver<M, float>::LambdaVector lf;
  REQUIRE(f.step(0.0f, qf, qdf, qddf));
  REQUIRE(f.forces(qf, qdf, qddf, 0.0f, lf));
  kinegen::Solver<M> d;
  q = d.initial_estimate();
  REQUIRE(d.step(0.0, q, qd, qdd));
  REQUIRE(d.forces(q, qd, qdd, 0.0, lambda));
  CHECK((lf.cast<double>() - lambda).cwiseAbs().maxCoeff() <= 1e-4 * lambda.cwiseAbs().maxCoeff());
}

namespace {
// The largest difference of the generated columns, with the step's factors reused, from the
// in-process ForceSolver of `analyze --forces` over [0, t1], relative to each row's largest
// force: from the in-process row's q, qd, qdd (a solve_step from that q keeps the factors
// at the same point; Newton's first step stays within rounding of it).
template <class M>
double reuse_against_in_process(const std::string& yaml, double t1) {
  const auto model = kc::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + yaml);
  const kc::ForceModel forces = kc::forces_for_analysis(*model);
  kc::ForceSolver solver(*model, forces);
  Generated<M, double> g;
  typename M::template StepFactors<double> factors;
  double worst = 0;
  int rows = 0;
  kc::run_analysis(*model, {0, t1, 360}, [&](const kc::StateRow& row) {
    std::vector<double> cols;
    REQUIRE(solver.solve(row.t, row.q, row.qd, row.qdd, cols));
    REQUIRE(
        M::solve_step(g.q, row.t, g.p, g.qd, g.qdd, g.options, no_trig<double>(), nullptr, &factors)
            .status == 0);
    REQUIRE(M::solve_forces(g.q, g.qd, g.qdd, row.t, g.p, g.lambda, g.options, &factors).status ==
            0);
    M::force_columns(g.q, row.t, g.p, g.lambda, g.columns);
    const double scale = largest(cols);
    for (int c = 0; c < M::num_force_columns; ++c)
      worst = std::max(worst, std::abs(g.columns[c] - cols[c]) / scale);
    ++rows;
  });
  REQUIRE(rows == 361);
  return worst;
}
}  // namespace

TEST_CASE("generated forces with the step's factors equal the in-process ForceSolver",
          "[forces][generated][reuse]") {
  const double balanced = reuse_against_in_process<km::four_bar_balanced>(
      "/examples/forces/four_bar_balanced.yaml", 1.0);
  const double torn = reuse_against_in_process<km::closed_chain_masses>(
      "/tests/mechanisms/closed_chain_masses.yaml", 2 * kPi);
  INFO(
      "largest difference relative to the row's largest force (generated step's own "
      "kinematics): four_bar_balanced "
      << balanced << ", closed_chain_masses " << torn);
  CHECK(balanced <= 1e-12);
  CHECK(torn <= 1e-12);
}

// Solver::forces reuses its last step's factors only for the step's t, q, parameters and
// options: after params().b changes (or an option), it factors again, as a fresh Solver does.
TEST_CASE("Solver::forces after a parameter or an option change equals a fresh Solver's",
          "[forces][generated][reuse]") {
  using M = km::four_bar_balanced;
  using S = kinegen::Solver<M>;
  S solver;
  S::Vector q = S::initial_estimate(), qd, qdd;
  for (int i = 0; i < 3; ++i) REQUIRE(solver.step(0.01 * i, q, qd, qdd));
  const double t = 0.02;
  M::Params p;
  p.b = 0.36;
  solver.system().params().b = p.b;
  S::LambdaVector changed, fresh_lambda;
  REQUIRE(solver.forces(q, qd, qdd, t, changed));
  S fresh(p);
  REQUIRE(fresh.forces(q, qd, qdd, t, fresh_lambda));
  INFO("max |lambda| " << fresh_lambda.cwiseAbs().maxCoeff());
  CHECK((changed - fresh_lambda).cwiseAbs().maxCoeff() <=
        1e-12 * fresh_lambda.cwiseAbs().maxCoeff());
  // An option that the factors depend on: a min_rcond no block passes is a refusal, not the
  // old factors' answer.
  S other;
  S::Vector q2 = S::initial_estimate(), qd2, qdd2;
  for (int i = 0; i < 3; ++i) REQUIRE(other.step(0.01 * i, q2, qd2, qdd2));
  other.options().min_rcond = 2;
  S::LambdaVector refused;
  CHECK(other.forces(q2, qd2, qdd2, t, refused).status == kinegen::Status::kSingular);
}
