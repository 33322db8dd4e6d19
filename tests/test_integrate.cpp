// The integrator kernel (kernels/integrate.hpp) on its own, against closed forms: the harmonic
// oscillator (RK4's global error of order 4, SDIRK2's of order 2), a stiff spring (RK4 at h w = 10
// grows without bound, the implicit step decays), the damped oscillator (the closed form; the
// implicit step's energy never grows), and the difference Jacobian against the exact one.
#include <catch2/catch.hpp>
#include <cmath>
#include <kinegen/kernels/integrate.hpp>

namespace {

using K = kinegen::kernels::IntegrateKernel;

// x'' + 2 zeta w x' + w^2 x = 0 as x = (position, rate).
struct Oscillator {
  double w, zeta;
  int operator()(double, const double* x, double* xd) const {
    xd[0] = x[1];
    xd[1] = -w * w * x[0] - 2 * zeta * w * x[1];
    return 0;
  }
  int jacobian(double, const double*, const double*, double* j) const {
    j[0] = 0;
    j[1] = 1;
    j[2] = -w * w;
    j[3] = -2 * zeta * w;
    return 0;
  }
  // The closed form from x(0) = 1, x'(0) = 0 (under-damped).
  double position(double t) const {
    const double wd = w * std::sqrt(1 - zeta * zeta);
    return std::exp(-zeta * w * t) * (std::cos(wd * t) + zeta * w / wd * std::sin(wd * t));
  }
  double energy(const double* x) const { return 0.5 * (x[1] * x[1] + w * w * x[0] * x[0]); }
};

constexpr double kScale[2] = {1, 1};

// The error at t1 of n steps from (1, 0).
template <bool kImplicit>
double error_after(const Oscillator& o, double t1, int n) {
  double x[2] = {1, 0};
  const double h = t1 / n;
  for (int i = 0; i < n; ++i) {
    const double t = i * h;
    int s = 0;
    if constexpr (kImplicit) {
      s = K::_sdirk2_step<2>(
          t, h, x, kScale, o,
          [&](double tt, const double* xx, const double* f, double* j) {
            return o.jacobian(tt, xx, f, j);
          },
          10, 1e-14);
    } else {
      s = K::_rk4_step<2>(t, h, x, o);
    }
    REQUIRE(s == 0);
  }
  return std::abs(x[0] - o.position(t1));
}

}  // namespace

TEST_CASE("RK4's global error on the harmonic oscillator is of order 4", "[integrate]") {
  const Oscillator o{2.0, 0.0};
  const double e1 = error_after<false>(o, 3.0, 200), e2 = error_after<false>(o, 3.0, 400);
  CHECK(std::log2(e1 / e2) == Approx(4).margin(0.1));
  CHECK(error_after<false>(o, 3.0, 3000) < 1e-12);
}

TEST_CASE("SDIRK2's global error is of order 2; the damped oscillator's closed form",
          "[integrate]") {
  const Oscillator o{2.0, 0.0};
  const double e1 = error_after<true>(o, 3.0, 200), e2 = error_after<true>(o, 3.0, 400);
  CHECK(std::log2(e1 / e2) == Approx(2).margin(0.1));
  const Oscillator damped{3.0, 0.1};
  CHECK(error_after<false>(damped, 2.0, 2000) < 1e-11);
  CHECK(error_after<true>(damped, 2.0, 20000) < 1e-6);
}

TEST_CASE("a stiff spring: RK4 at h w = 10 blows up, the implicit step decays", "[integrate]") {
  const Oscillator o{1000.0, 0.001};
  const double h = 0.01;
  double explicit_x[2] = {1, 0}, implicit_x[2] = {1, 0};
  const auto jac = [&](double t, const double* x, const double* f, double* j) {
    return o.jacobian(t, x, f, j);
  };
  double energy = o.energy(implicit_x);
  for (int i = 0; i < 100; ++i) {
    REQUIRE(K::_rk4_step<2>(i * h, h, explicit_x, o) == 0);
    int iterations = 0;
    REQUIRE(K::_sdirk2_step<2>(i * h, h, implicit_x, kScale, o, jac, 10, 1e-12, &iterations) == 0);
    CHECK(iterations <= 4);  // linear: one Newton step per stage and one that confirms it
    const double e = o.energy(implicit_x);
    CHECK(e <= energy);  // L-stable: the spring's energy never grows
    energy = e;
  }
  CHECK(!(std::abs(explicit_x[0]) < 1e10));  // RK4's factor at h w = 10 is far above 1
  CHECK(o.energy(implicit_x) < 1e-6 * o.energy(std::array<double, 2>{1, 0}.data()));
}

TEST_CASE("the difference Jacobian, the implicit step's fallback, is the exact one to sqrt(eps)",
          "[integrate]") {
  const Oscillator o{5.0, 0.3};
  const double x[2] = {0.7, -1.2};
  double f[2], exact[4], diff[4];
  o(0, x, f);
  o.jacobian(0, x, f, exact);
  REQUIRE(K::_difference_jacobian<2>(0.0, x, f, kScale, diff, o) == 0);
  for (int i = 0; i < 4; ++i) CHECK(diff[i] == Approx(exact[i]).margin(1e-6));
  // A failing right-hand side ends the step with its status and leaves x as it was.
  double y[2] = {1, 2};
  const auto failing = [](double, const double*, double*) { return 3; };
  CHECK(K::_rk4_step<2>(0.0, 0.1, y, failing) == 3);
  CHECK((y[0] == 1 && y[1] == 2));
}
