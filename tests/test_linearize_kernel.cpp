// The dynamics tangent kernel (runtime/include/kinegen/kernels/linearize.hpp) on its own: the
// inertia forces' tangent against the complex step of the inertia forces, the Hessian
// contractions against dense loops, and _dynamics_tangent on a body held at its pivot by
// hand-written pieces, in float, double and complex, against the closed form
// d(zdd)/dz = m g a sin(z) / (J + m a^2).
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <kinegen/kernels/linearize.hpp>
#include <vector>

namespace {

using L = kinegen::kernels::LinearizeKernel;
using C = std::complex<double>;

}  // namespace

TEST_CASE("linearize kernel: the inertia forces' tangent is their complex step",
          "[linearize_kernel]") {
  // Two bodies and an extra coordinate; centres of mass off the frames' origins.
  const int nb = 2, nq = 7;
  const double m[] = {1.3, 0.7}, j[] = {0.02, 0.11}, com[][2] = {{0.3, -0.1}, {-0.2, 0.45}};
  const double q[] = {0.1, -0.2, 0.9, 1.0, 0.5, -2.1, 0.3};
  const double qd[] = {0.4, -1.1, 2.3, -0.6, 0.2, -1.7, 0.5};
  const double qdd[] = {-3.0, 1.2, 4.1, 0.7, -2.2, 0.9, 0.0};
  const double dq[] = {0.3, -0.5, 0.8, 0.1, 0.9, -0.4, 0.2};
  const double dqd[] = {-0.2, 0.6, 0.35, 0.7, -0.1, 1.3, -0.8};
  // f(s) = M(q + s dq) qdd + h(q + s dq, qd + s dqd) by the complex step in s.
  const double h = 1e-30;
  std::vector<C> ax(nb), ay(nb), cm(m, m + nb), cj(j, j + nb), cqd(nq), cqdd(qdd, qdd + nq),
      out(nq);
  for (int b = 0; b < nb; ++b) {
    const C phi = C(q[3 * b + 2], h * dq[3 * b + 2]);
    ax[b] = std::cos(phi) * com[b][0] - std::sin(phi) * com[b][1];
    ay[b] = std::sin(phi) * com[b][0] + std::cos(phi) * com[b][1];
  }
  for (int k = 0; k < nq; ++k) cqd[k] = C(qd[k], h * dqd[k]);
  L::_inertia_forces(nb, nq, cm.data(), cj.data(), ax.data(), ay.data(), cqd.data(), cqdd.data(),
                     out.data());
  std::vector<double> rax(nb), ray(nb), tangent(nq, 0.0);
  for (int b = 0; b < nb; ++b) {
    rax[b] = ax[b].real();
    ray[b] = ay[b].real();
  }
  std::vector<double> c(5 * nb), forces(nq);
  L::_inertia_forces(nb, nq, m, j, rax.data(), ray.data(), qd, qdd, forces.data(), c.data());
  L::_inertia_tangent(nb, rax.data(), ray.data(), c.data(), dq, dqd, tangent.data());
  for (int k = 0; k < nq; ++k) {
    INFO("coordinate " << k);
    CHECK(tangent[k] == Approx(out[k].imag() / h).epsilon(1e-14).margin(1e-15));
  }
}

TEST_CASE("linearize kernel: Hessian contractions equal the dense sums", "[linearize_kernel]") {
  // Entries (row, j <= k) of a symmetric second-derivative tensor of 2 rows in 3 coordinates.
  const int rows[] = {0, 0, 1, 1, 1}, js[] = {0, 1, 0, 2, 2}, kk[] = {2, 1, 1, 2, 2};
  const double values[] = {0.5, -1.5, 2.0, 0.25, 0.75};  // (1, 2, 2) twice: they add
  const L::_Hessian<double> hs{5, rows, js, kk, values};
  double t[2][3][3] = {};
  for (int e = 0; e < 5; ++e) {
    t[rows[e]][js[e]][kk[e]] += values[e];
    if (js[e] != kk[e]) t[rows[e]][kk[e]][js[e]] += values[e];
  }
  const double v[] = {0.3, -1.2, 0.8}, dq[] = {1.1, 0.4, -0.6}, lambda[] = {2.0, -0.5};
  double out[2] = {}, out_t[3] = {};
  L::_hessian_times(hs, v, dq, out);
  L::_hessian_transposed(hs, lambda, dq, out_t);
  for (int r = 0; r < 2; ++r) {
    double want = 0;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) want += t[r][a][b] * v[a] * dq[b];
    CHECK(out[r] == Approx(want).epsilon(1e-15));
  }
  for (int a = 0; a < 3; ++a) {
    double want = 0;
    for (int r = 0; r < 2; ++r)
      for (int b = 0; b < 3; ++b) want += lambda[r] * t[r][a][b] * dq[b];
    CHECK(out_t[a] == Approx(want).epsilon(1e-15));
  }
}

namespace {

// One body pinned at its frame's origin by x = 0, y = 0, its angle the free coordinate:
// Phi = [x, y, phi - z], Phi_q = I, B = e_phi; gravity -g on a centre of mass (a, 0):
// Q^A = (0, -m g, -m g a cos phi). zdd = -m g a cos z / (J + m a^2), so
// d(zdd)/dz = m g a sin z / (J + m a^2) and d(zdd)/dzd = 0; a torque input u on it gives
// d(zdd)/du = 1 / (J + m a^2).
template <class T>
void check_pinned_body() {
  const T m(1.5), j(0.2), a(0.4), g(9.81), z(0.7), zd(1.3);
  const T ip = j + m * a * a;
  const T q[] = {T(0), T(0), z}, qd[] = {T(0), T(0), zd};
  const T zdd = -m * g * a * std::cos(z) / ip;
  const T qdd[] = {T(0), T(0), zdd};
  const T b[] = {T(0), T(0), T(1)};
  const T ax[] = {a * std::cos(z)}, ay[] = {a * std::sin(z)};
  const T applied[] = {T(0), -m * g, -m * g * a * std::cos(z) + T(0)};
  // Input slots: z 0, zd 1, zdd 2 (the free item's), the torque's 3.
  const int w_row[] = {2}, w_col0[] = {0}, w_col1[] = {1}, w_col2[] = {2}, q_col[] = {2};
  const int u_row[] = {2}, u_col[] = {3};
  const T minus_one[] = {T(-1)}, one[] = {T(1)};
  const T stiffness[] = {m * g * a * std::sin(z)};  // d Q^A_phi / d phi
  L::_TangentPoint<T> p;
  p.nq = 3;
  p.nf = 1;
  p.nb = 1;
  p.q = q;
  p.qd = qd;
  p.qdd = qdd;
  p.b = b;
  p.mass = &m;
  p.inertia = &j;
  p.ax = ax;
  p.ay = ay;
  p.applied = applied;
  p.phi_w = {1, w_row, w_col0, minus_one};
  p.nu_w = {1, w_row, w_col1, minus_one};
  p.gamma_w = {1, w_row, w_col2, minus_one};
  p.applied_q = {1, w_row, q_col, stiffness};
  p.applied_w = {1, u_row, u_col, one};
  const int slots[] = {0, 1, 3};
  T out[3];
  std::vector<T> work(L::_tangent_work_size(3, 1, 3));
  int calls = 0, columns = 0;
  const auto identity = [&](T* b, T* x, int m) {  // Phi_q = I
    for (int i = 0; i < 3 * m; ++i) x[i] = b[i];
    columns += m;
    return ++calls, 0;
  };
  REQUIRE(L::_dynamics_tangent(p, 3, slots, out, work.data(), identity, identity) == 0);
  CHECK(calls == 3);  // the solves batched: Phi_q^T once, Phi_q twice
  CHECK(columns == 2 + 3 + 3);
  // The same with what a dynamics() gives (M B, B^T M B's factors) and the free coordinate's
  // value and rate known (their dq and dqd are B): the same numbers, from 3 columns fewer.
  {
    L::_TangentPoint<T> given = p;
    T mb[3], mz[1];
    L::_mass_times(1, 3, &m, &j, ax, ay, b, mb);
    mz[0] = L::_dot(3, b, mb);
    REQUIRE(L::_ldlt_factor(1, mz) > 0);
    const int known[] = {0, 1, -1};  // z, zd (nf + 0), the torque
    given.mb = mb;
    given.mz = mz;
    given.known = known;
    T again[3];
    columns = 0;
    REQUIRE(L::_dynamics_tangent(given, 3, slots, again, work.data(), identity, identity) == 0);
    CHECK(columns == 2 + 1 + 2);
    for (int k = 0; k < 3; ++k) CHECK(again[k] == out[k]);
    // The torque moves neither q nor qd (_kStill), and r_a can be non-zero on row 2 only (the
    // only row of gamma_w; Phi_qq, gamma_q and gamma_qd are empty): its two solves spared too.
    const int still[] = {0, 1, L::_kStill}, r_rows[] = {2};
    given.known = still;
    given.n_r_rows = 1;
    given.r_rows = r_rows;
    columns = 0;
    REQUIRE(L::_dynamics_tangent(given, 3, slots, again, work.data(), identity, identity) == 0);
    CHECK(columns == 2 + 0 + 1);
    for (int k = 0; k < 3; ++k) CHECK(again[k] == out[k]);
  }
  using R = decltype(std::abs(T()));
  const R tol = std::is_same_v<T, float> ? R(1e-5) : R(1e-14);
  using std::abs;
  CHECK(abs(out[0] - m * g * a * std::sin(z) / ip) <= tol * abs(out[0]));
  CHECK(abs(out[1]) <= tol);
  CHECK(abs(out[2] - T(1) / ip) <= tol * abs(out[2]));
  // A massless body: M_z is singular, status 2.
  const T zero(0);
  p.mass = &zero;
  p.inertia = &zero;
  CHECK(L::_dynamics_tangent(p, 3, slots, out, work.data(), identity, identity) == 2);
}

}  // namespace

TEST_CASE("linearize kernel: a pinned body's tangent in float, double and complex",
          "[linearize_kernel]") {
  check_pinned_body<double>();
  check_pinned_body<float>();
  check_pinned_body<C>();
}
