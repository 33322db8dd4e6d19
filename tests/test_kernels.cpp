// The block-solver kernels (runtime/include/kinegen/kernels/), compiled on their own: the LU
// against Eigen, the rotation series and the sin/cos cache against long double and std::sin,
// the Newton step criterion in float; and the generated headers carry the kernels' text
// unchanged, only those they call.
#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <kinegen/kernels/block_linear.hpp>
#include <kinegen/kernels/lu.hpp>
#include <kinegen/kernels/newton.hpp>
#include <kinegen/kernels/trig_cache.hpp>
#include <random>
#include <sstream>
#include <string>
#include <utility>

namespace {

using Lu = kinegen::kernels::LuKernel;
using Trig = kinegen::kernels::TrigCacheKernel;
using Newton = kinegen::kernels::NewtonKernel;

// Factors a random K x K matrix (and a singular one) and checks solve, determinant sign,
// condition estimate and singular detection against Eigen.
template <int K>
void check_lu(std::mt19937& rng) {
  using Mat = Eigen::Matrix<double, K, K, Eigen::RowMajor>;
  using Vec = Eigen::Matrix<double, K, 1>;
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 200; ++trial) {
    Mat m;
    for (int i = 0; i < K; ++i)
      for (int j = 0; j < K; ++j) m(i, j) = u(rng);
    Vec b;
    for (int i = 0; i < K; ++i) b[i] = u(rng);
    Mat a = m;
    int piv[K];
    const double ratio = Lu::_lu_factor<K>(a.data(), piv);
    const Eigen::PartialPivLU<Mat> ref(m);
    const auto diag = ref.matrixLU().diagonal().cwiseAbs();
    // The same pivots as Eigen's partial pivoting, so the same ratio (to rounding).
    CHECK(ratio == Approx(diag.minCoeff() / diag.maxCoeff()).epsilon(1e-12));
    Vec x = b;
    Lu::_lu_solve<K>(a.data(), piv, x.data());
    const double cond = m.norm() * m.inverse().norm();
    CHECK((m * x - b).norm() <= 64 * 2.2e-16 * cond * (m.norm() * x.norm() + b.norm()));
    CHECK(Lu::_lu_det_sign<K>(a.data(), piv) == (m.determinant() > 0 ? 1 : -1));
    // The transposed solve with the same factors: m^T y = b.
    Vec y = b;
    Lu::_lu_solve_transposed<K>(a.data(), piv, y.data());
    CHECK((m.transpose() * y - b).norm() <=
          64 * 2.2e-16 * cond * (m.norm() * y.norm() + b.norm()));
    // Condition estimate: 1 / |A^-1|_inf of the equilibrated A = R m D, exactly (K solves).
    double d[K], row_max[K];
    for (int j = 0; j < K; ++j) d[j] = j % 2 == 0 ? 1.0 : 2.5;
    Lu::_row_max<K>(m.data(), d, row_max);
    Mat scaled;
    for (int i = 0; i < K; ++i)
      for (int j = 0; j < K; ++j) scaled(i, j) = m(i, j) * d[j] / row_max[i];
    const double inv_norm = scaled.inverse().cwiseAbs().rowwise().sum().maxCoeff();
    const double rcond = Lu::_lu_rcond<K>(a.data(), piv, row_max, d);
    CHECK(rcond == Approx(1 / inv_norm).epsilon(1e-9));
    // Within a factor K of the true reciprocal condition number (infinity norm).
    const double true_rcond = 1 / (scaled.cwiseAbs().rowwise().sum().maxCoeff() * inv_norm);
    CHECK(rcond >= true_rcond * (1 - 1e-12));
    CHECK(rcond <= K * true_rcond * (1 + 1e-12));
  }
  if constexpr (K >= 2) {
    // Singular: the last row a combination of the others (exactly representable).
    Mat m;
    for (int i = 0; i < K; ++i)
      for (int j = 0; j < K; ++j) m(i, j) = std::round(8 * u(rng)) / 4;
    for (int j = 0; j < K; ++j) m(K - 1, j) = m(0, j) + (K > 2 ? m(1, j) : m(0, j));
    int piv[K];
    Mat a = m;
    const double ratio = Lu::_lu_factor<K>(a.data(), piv);
    CHECK(!(ratio > 1e-13));
    // Not finite: reported as NaN.
    a = m;
    a(0, 0) = std::nan("");
    CHECK(std::isnan(Lu::_lu_factor<K>(a.data(), piv)));
  } else {
    double a = 0;
    int piv[1];
    CHECK(Lu::_lu_factor<1>(&a, piv) == 0);
  }
}

template <int... K>
void check_lu_sizes(std::mt19937& rng, std::integer_sequence<int, K...>) {
  (check_lu<K + 1>(rng), ...);
}

// The kernel text of a file: the lines between its markers (as cmake/embed_kernels.cmake).
std::string kernel_body(const std::string& source, const std::string& name) {
  const std::string begin = "// kinegen-kernel-begin " + name + "\n";
  const std::string end = "// kinegen-kernel-end " + name + "\n";
  const auto b = source.find(begin);
  const auto e = source.find(end);
  REQUIRE(b != std::string::npos);
  REQUIRE(e != std::string::npos);
  std::string text = source.substr(b + begin.size(), e - b - begin.size());
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

std::string read(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

TEST_CASE("LU kernel agrees with Eigen on random and singular matrices, K = 1..6", "[kernels]") {
  std::mt19937 rng(12);
  check_lu_sizes(rng, std::make_integer_sequence<int, 6>{});
}

// A model's structure tables for the block_linear kernel, as the emitter writes them: blocks
// of sizes 1, 3, 2, 1 over 7 coordinates, rows and coordinates permuted.
struct LinearModel {
  static constexpr int nq = 7, nc = 7, num_blocks = 4, max_block_size = 3;
  static constexpr std::array<int, num_blocks + 1> block_begin = {0, 1, 4, 6, 7};
  static constexpr std::array<int, nc> block_rows = {3, 0, 5, 6, 1, 4, 2};
  static constexpr std::array<int, nq> block_cols = {6, 1, 2, 4, 0, 5, 3};
  static constexpr std::array<int, nq> coordinate_block = {2, 1, 1, 3, 1, 2, 0};
  static constexpr std::array<int, nq> coordinate_slot = {4, 1, 2, 6, 3, 5, 0};
  static constexpr std::array<double, nq> coordinate_scales = {1, 2, 1, 0.5, 1, 3, 1};
  // Filled by the test: a block-lower-triangular pattern, entries sorted by row.
  static inline std::array<int, nc + 1> jac_row_begin{};
  static inline std::array<int, nc * nq> jac_cols{};
};

TEST_CASE("block_linear kernel: Phi_q X = B and Phi_q^T Y = B through the blocks", "[kernels]") {
  using S = LinearModel;
  using Linear = kinegen::kernels::BlockLinearKernel;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 50; ++trial) {
    // Every row has its own block's coordinates and a random subset of earlier blocks'; the
    // i-th row of a block is strong in the block's i-th coordinate, so blocks are regular.
    std::array<int, S::nc> row_block{}, diagonal_col{};
    for (int k = 0; k < S::num_blocks; ++k)
      for (int i = S::block_begin[k]; i < S::block_begin[k + 1]; ++i) {
        row_block[S::block_rows[i]] = k;
        diagonal_col[S::block_rows[i]] = S::block_cols[i];
      }
    Eigen::MatrixXd j = Eigen::MatrixXd::Zero(S::nc, S::nq);
    std::vector<double> values;
    int e = 0;
    for (int r = 0; r < S::nc; ++r) {
      S::jac_row_begin[r] = e;
      const int k = row_block[r];
      for (int c = 0; c < S::nq; ++c) {
        const int bc = S::coordinate_block[c];
        if (bc > k || (bc < k && u(rng) < 0)) continue;
        j(r, c) = u(rng) + (c == diagonal_col[r] ? 3.0 : 0.0);
        S::jac_cols[e++] = c;
        values.push_back(j(r, c));
      }
    }
    S::jac_row_begin[S::nc] = e;
    constexpr int m = 2;
    Eigen::MatrixXd b = Eigen::MatrixXd::Random(S::nq, m), x(S::nq, m), y(S::nq, m);
    const kinegen::kernels::ReportKernel::BasicBlockOptions<double> o;
    const auto forward = Linear::_block_forward<S>(values.data(), b.data(), x.data(), m, o);
    REQUIRE(forward.status == 0);
    const Eigen::MatrixXd x_ref = j.fullPivLu().solve(b);
    const double cond = j.norm() * j.inverse().norm();
    CHECK((x - x_ref).norm() <= 1e-13 * cond * x_ref.norm());
    Eigen::MatrixXd work = b;
    const auto transposed = Linear::_block_transposed<S>(values.data(), work.data(), y.data(), m, o);
    REQUIRE(transposed.status == 0);
    const Eigen::MatrixXd y_ref = j.transpose().fullPivLu().solve(b);
    CHECK((y - y_ref).norm() <= 1e-13 * cond * y_ref.norm());
    CHECK(forward.rcond == transposed.rcond);
    CHECK(forward.rcond > 0);
    CHECK(forward.rcond <= 1);
    // A singular block: block 1's rows made dependent; both solves name block 1.
    std::vector<double> singular = values;
    for (int r : {0, 5})
      for (int q = S::jac_row_begin[r]; q < S::jac_row_begin[r + 1]; ++q)
        if (S::coordinate_block[S::jac_cols[q]] == 1) singular[q] = 0;
    const auto f2 = Linear::_block_forward<S>(singular.data(), b.data(), x.data(), m, o);
    CHECK(f2.status == 2);
    CHECK(f2.block == 1);
    work = b;
    const auto t2 = Linear::_block_transposed<S>(singular.data(), work.data(), y.data(), m, o);
    CHECK(t2.status == 2);
    CHECK(t2.block == 1);
    // A dead centre in a 1 x 1 block: its entry tiny next to the rest of its row (row 2, block
    // 3, which has entries in earlier blocks' coordinates). Phi_q is nearly singular although
    // the block alone is a non-zero number: both solves refuse it.
    std::vector<double> dead = values;
    bool off_block = false;
    for (int q = S::jac_row_begin[2]; q < S::jac_row_begin[3]; ++q) {
      if (S::coordinate_block[S::jac_cols[q]] == 3)
        dead[q] = 1e-17;
      else
        off_block = off_block || dead[q] != 0;
    }
    if (off_block) {
      const auto f4 = Linear::_block_forward<S>(dead.data(), b.data(), x.data(), m, o);
      CHECK(f4.status == 2);
      CHECK(f4.block == 3);
    }
    // A NaN in the last block's row, inside or outside the block: status 3 at the block that
    // meets it (forward: block 3, the row's; backward: the block of the entry's coordinate).
    std::vector<double> nan = values;
    const int at = S::jac_row_begin[2] + trial % (S::jac_row_begin[3] - S::jac_row_begin[2]);
    nan[at] = std::nan("");
    const auto f3 = Linear::_block_forward<S>(nan.data(), b.data(), x.data(), m, o);
    CHECK(f3.status == 3);
    CHECK(f3.block == 3);
    work = b;
    const auto t3 = Linear::_block_transposed<S>(nan.data(), work.data(), y.data(), m, o);
    CHECK(t3.status == 3);
    CHECK(t3.block == S::coordinate_block[S::jac_cols[at]]);
  }
}

TEST_CASE("float LU computes in float", "[kernels]") {
  float a[4] = {2, 1, 1, 3}, b[2] = {3, 4};
  int piv[2];
  const auto ratio = Lu::_lu_factor<2>(a, piv);
  STATIC_REQUIRE(std::is_same_v<decltype(ratio), const float>);
  Lu::_lu_solve<2>(a, piv, b);
  CHECK(b[0] == Approx(1).epsilon(1e-6));
  CHECK(b[1] == Approx(1).epsilon(1e-6));
}

// Rotation by |d| <= 1/32 from exact (rounded) sin and cos: against long double sin and cos of
// the rotated angle, at most 2 ulps of 1 (2^-52 absolute: the rounding of the inputs, half an
// ulp each, and of the rotation's few operations).
TEST_CASE("rotation series within 2 ulps of long double over |d| <= 1/32", "[kernels]") {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> angle(-10, 10), small(-1.0 / 32, 1.0 / 32);
  const double ulp = std::ldexp(1.0, -52);
  double worst = 0;
  for (int k = 0; k < 200000; ++k) {
    const double a = angle(rng);
    const double d = k % 4 == 0 ? small(rng) * 1e-4 : small(rng);  // both series branches
    const double s0 = std::sin(a), c0 = std::cos(a);
    double s, c;
    Trig::_rotated(s0, c0, d, s, c);
    const long double exact = static_cast<long double>(a) + d;
    worst = std::max(worst, static_cast<double>(std::fabs(s - sinl(exact))));
    worst = std::max(worst, static_cast<double>(std::fabs(c - cosl(exact))));
  }
  INFO("largest error " << worst / ulp << " ulps of 1");
  CHECK(worst <= 2 * ulp);
}

// The cache over long random walks with jumps: every value one rotation from exact, so the
// error stays at the rotation's and does not grow.
TEST_CASE("trig cache over a random walk of 1e5 steps with jumps", "[kernels]") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> walk(-0.02, 0.02), jump(-50, 50), u(0, 1);
  Trig::BasicTrigCache<double, 6> cache;
  double angles[2] = {0.3, -2.0};
  const double ulp = std::ldexp(1.0, -52);
  double worst = 0;
  int recomputed = 0;
  for (int k = 0; k < 100000; ++k) {
    for (int slot = 0; slot < 2; ++slot) {
      angles[slot] += u(rng) < 0.001 ? jump(rng) : walk(rng);
      const double anchor = cache.values[3 * slot];
      double s, c;
      Trig::_trig(s, c, angles[slot], cache.data(), slot);
      recomputed += cache.values[3 * slot] != anchor;
      const long double exact = angles[slot];
      worst = std::max(worst, static_cast<double>(std::fabs(s - sinl(exact))));
      worst = std::max(worst, static_cast<double>(std::fabs(c - cosl(exact))));
    }
  }
  INFO("largest error " << worst / ulp << " ulps of 1, " << recomputed << " anchors");
  CHECK(worst <= 2 * ulp);
  CHECK(recomputed < 20000);  // mostly rotations
}

// A cache that was zero-filled (or overwritten) rather than constructed: its slots are not on
// the unit circle, so they are recomputed, never rotated from.
TEST_CASE("trig cache recomputes zero-filled and garbage slots", "[kernels]") {
  for (const double fill : {0.0, 1.0, 1e300}) {
    double cache[3] = {fill, fill, fill};
    double s, c;
    Trig::_trig(s, c, 0.01, cache, 0);
    CHECK(s == std::sin(0.01));
    CHECK(c == std::cos(0.01));
    CHECK(cache[0] == 0.01);
  }
  Trig::BasicTrigCache<float, 3> typed;
  CHECK(std::isnan(typed.values[0]));
  float s, c;
  Trig::_trig(s, c, 0.5f, typed.data(), 0);
  CHECK(s == std::sin(0.5f));
}

TEST_CASE("Newton step criterion: tolerance plus rounding in the scalar's type", "[kernels]") {
  // float: a step of a few ulps of an angle of 100 rad converges whatever the tolerance asked;
  // double keeps 1e-10 near 1.
  CHECK(Newton::_step_converged(3e-5f, 100.f, 1e-10f));
  CHECK_FALSE(Newton::_step_converged(1e-3f, 100.f, 1e-10f));
  CHECK(Newton::_step_converged(1e-10, 1.0, 1e-10));
  CHECK_FALSE(Newton::_step_converged(2e-10, 1.0, 1e-10));
  // An angle of 6e6 rad: its ulp (9.3e-10) passes, 1e-6 does not.
  CHECK(Newton::_step_converged(9.3e-10, 6e6, 1e-10));
  CHECK_FALSE(Newton::_step_converged(1e-6, 6e6, 1e-10));
  // Defaults follow the scalar.
  const Newton::BasicBlockOptions<float> of;
  const Newton::BasicBlockOptions<double> od;
  CHECK(of.tolerance == Approx(std::ldexp(1.0, -15)));
  CHECK(od.tolerance == Approx(std::ldexp(1.0, -33)));
  CHECK(od.residual_tolerance == Approx(std::ldexp(1.0, -26)));
  CHECK(of.singular_pivot_ratio == Approx(512 * std::ldexp(1.0, -23)));
}

TEST_CASE("_newton_end: budget, inconsistency, condition and branch", "[kernels]") {
  const Newton::BasicBlockOptions<double> o;
  Newton::BlockReport<double> r;
  signed char signs[3] = {0, 0, 0};
  CHECK(Newton::_newton_end(r, 1, 2, true, o, 1e-12, 0, 1e-14, 2.0, 0.5, -1, signs));
  CHECK(signs[1] == -1);
  CHECK(Newton::_newton_end(r, 1, 2, true, o, 1e-12, 0, 1e-14, 2.0, 0.5, -1, signs));
  CHECK_FALSE(Newton::_newton_end(r, 1, 2, true, o, 1e-12, 0, 1e-14, 2.0, 0.5, 1, signs));
  CHECK(r.status == 6);
  CHECK(r.block == 1);
  Newton::BasicBlockOptions<double> fixed;
  fixed.fixed_iterations = 3;
  Newton::BlockReport<double> rf;
  CHECK_FALSE(Newton::_newton_end(rf, 0, 3, false, fixed, 0.5, 0, 2.2, 1.0, 0.5, 1, nullptr));
  CHECK(rf.status == 5);
  CHECK(rf.residual == 2.2);
  Newton::BlockReport<double> ri;
  CHECK_FALSE(Newton::_newton_end(ri, 0, 5, true, o, 1e-14, 0, 1e-3, 1.0, 0.5, 1, nullptr));
  CHECK(ri.status == 4);
  Newton::BlockReport<double> rs;
  CHECK_FALSE(Newton::_newton_end(rs, 2, 5, true, o, 1e-14, 0, 1e-15, 1.0, 1e-14, 1, nullptr));
  CHECK(rs.status == 2);
  CHECK(rs.rcond == 1e-14);
}

// Newton on f(x) = x^2 - c with the policy's decisions, as a 1 x 1 block whose row also holds
// a coupling of size 1 (so that its condition is |f'| / max(|f'|, 1), as _coupled_rcond
// measures a block within Phi_q). Returns the verdict's status and the iteration count.
namespace {
std::pair<int, int> newton_on_square(double c, double x) {
  const Newton::BasicBlockOptions<double> o;
  double step = 0;
  bool converged = false;
  int it = 0, linear = 0;
  while (!converged && it < o.max_iterations) {
    ++it;
    const double dx = (x * x - c) / (2 * x);
    x -= dx;
    const double previous = step;
    step = std::abs(dx);
    linear += Newton::_linear_step(step, previous);
    converged = Newton::_step_converged(step, std::abs(x), o.tolerance);
  }
  const double slope = std::abs(2 * x);
  const double rcond = slope / std::max(slope, 1.0);
  Newton::BlockReport<double> r;
  const double residual = std::abs(x * x - c) / std::max(slope, 1.0);
  Newton::_newton_end(r, 0, it, converged, o, step, linear, residual, std::abs(x), rcond, 1,
                      nullptr);
  return {r.status, it};
}
}  // namespace

TEST_CASE("Newton policy: linear convergence onto a singular root is singular", "[kernels]") {
  // A double root (c = 0, f' = 0 there): Newton halves the error each step, converging only
  // linearly; the step criterion is met at a point whose condition is about the step.
  const auto [s0, n0] = newton_on_square(0.0, 0.01);
  CHECK(n0 > 20);
  CHECK(s0 == 2);
  // Simple roots, well and poorly conditioned (f' = 2 and 2e-3 at the root): quadratic, fine.
  CHECK(newton_on_square(1.0, 1.3).first == 0);
  CHECK(newton_on_square(1e-6, 1.0).first == 0);
  // A root close to double (c = 1e-14, f' = 2e-7 there): Newton needs 23 halvings to get
  // near it, and the condition there is below sqrt(min_rcond): singular as well.
  CHECK(newton_on_square(1e-14, 1.0).first == 2);
  // The rule alone: a quadratic step is not linear, a halving is; the first step is neither.
  CHECK(Newton::_linear_step(1e-12, 1e-6) == 0);
  CHECK(Newton::_linear_step(5e-11, 1e-10) == 1);
  CHECK(Newton::_linear_step(5e-11, 0.0) == 0);
  CHECK(Newton::_poorly_conditioned(1e-8, 1.8e-12));
  CHECK_FALSE(Newton::_poorly_conditioned(1e-5, 1.8e-12));
  // Well conditioned, linear or not: converged.
  CHECK(Newton::_newton_status(false, true, true, true, 1e-15, 0.5, 1.8e-12) == 0);
  CHECK(Newton::_newton_status(false, true, true, true, 1e-15, 1e-8, 1.8e-12) == 2);
  // Out of iterations while converging linearly at poor condition: singular, not "slow".
  CHECK(Newton::_newton_status(false, false, false, true, 1e-9, 1e-8, 1.8e-12) == 2);
  CHECK(Newton::_newton_status(false, false, false, false, 1e-9, 1e-8, 1.8e-12) == 1);
  // Poorly conditioned but not reached linearly: converged (a regular root whose condition
  // only bounds the answer's sensitivity).
  CHECK(Newton::_newton_status(false, true, true, false, 1e-15, 1e-8, 1.8e-12) == 0);
}

TEST_CASE("Newton policy: stalling, damping and a policy in another scalar's epsilon",
          "[kernels]") {
  CHECK(Newton::_stalled(1e-21, 1e-21, 1e-20));
  CHECK_FALSE(Newton::_stalled(1e-21, 2e-21, 1e-20));  // still decreasing
  CHECK_FALSE(Newton::_stalled(1e-19, 1e-19, 1e-20));  // above the floor
  CHECK_FALSE(Newton::_stalled(1e-21, 0.0, 1e-20));    // first step
  CHECK(Newton::_accept_step(0.5, 1.0, 0, 8));
  CHECK_FALSE(Newton::_accept_step(2.0, 1.0, 0, 8));
  CHECK(Newton::_accept_step(2.0, 1.0, 8, 8));  // halvings spent
  CHECK_FALSE(Newton::_accept_step(std::numeric_limits<double>::quiet_NaN(), 1.0, 3, 8));
  CHECK(Newton::_accept_step(2e-14, 1e-14, 0, 8));  // at the rounding floor: noise
  // A policy in long double judged with double's epsilon equals double's.
  const long double eps = std::numeric_limits<double>::epsilon();
  CHECK(Newton::_step_converged(9.3e-10L, 6e6L, 1e-10L, eps));
  CHECK_FALSE(Newton::_step_converged(9.3e-10L, 6e6L, 1e-10L));
}

// Generated headers paste the kernel files' text unchanged, and only the kernels they call.
TEST_CASE("generated headers carry the kernel text unchanged", "[kernels]") {
  const std::filesystem::path root = KINEGEN_SOURCE_DIR;
  const char* kernels[] = {"report",       "lu",         "rotation", "trig_cache", "newton",
                           "block_linear", "motion_law", "dynamics", "linearize",  "integrate"};
  int headers = 0;
  for (const auto& e : std::filesystem::directory_iterator(root / "generated")) {
    const std::string header = read(e.path());
    if (header.find("has_block_solver = true") == std::string::npos) continue;
    ++headers;
    for (const char* name : kernels) {
      const std::string body = kernel_body(
          read(root / "runtime/include/kinegen/kernels" / (std::string(name) + ".hpp")), name);
      const std::string begin =
          std::string("// ---- kinegen kernel ") + name + " (kinegen/kernels/" + name + ".hpp)\n";
      const std::string end = std::string("  // ---- end of kinegen kernel ") + name + "\n";
      const auto b = header.find(begin);
      if (b == std::string::npos) continue;
      const auto e2 = header.find(end, b);
      REQUIRE(e2 != std::string::npos);
      INFO(e.path().filename() << ": kernel " << name);
      CHECK(header.substr(b + begin.size(), e2 - b - begin.size()) == body);
    }
    CHECK(header.find("// ---- kinegen kernel report") != std::string::npos);
  }
  CHECK(headers >= 4);
  // Only the kernels a model calls. The four-bar's 2 x 2 block needs the LU. The slider-crank's
  // block functions (1 x 1 blocks only) do not; its header carries the LU only for the block
  // solves of solve_sensitivity, and its --fold-params header (no sensitivities) not at all.
  CHECK(read(root / "generated/four_bar.hpp").find("kinegen kernel lu") != std::string::npos);
  std::string slider = read(root / "generated/slider_crank.hpp");
  CHECK(slider.find("kinegen kernel lu") != std::string::npos);
  CHECK(slider.find("_block_forward<_model>(") != std::string::npos);
  for (const char* name : kernels) {  // the code outside the kernels
    const std::string begin = std::string("// ---- kinegen kernel ") + name + " (";
    const std::string end = std::string("// ---- end of kinegen kernel ") + name + "\n";
    const auto b = slider.find(begin);
    if (b != std::string::npos) slider.erase(b, slider.find(end, b) + end.size() - b);
  }
  CHECK(slider.find("_lu_") == std::string::npos);
  const std::string folded =
      read(std::filesystem::path(KINEGEN_FOLDED_DIR) / "slider_crank_folded.hpp");
  CHECK(folded.find("has_sensitivity = false") != std::string::npos);
  CHECK(folded.find("kinegen kernel lu") == std::string::npos);
  CHECK(folded.find("kinegen kernel block_linear") == std::string::npos);
}
