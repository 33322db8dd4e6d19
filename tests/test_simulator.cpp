// kinegen::Simulator (runtime/include/kinegen/simulator.hpp) on generated headers, against
// closed forms: the pendulum released from horizontal reaches the other horizontal at half
// its period 2 sqrt(I / (m g a)) K(1/2), with its energy kept (RK4) or nearly (the implicit
// step); the implicit step on exact Jacobians needs few Newton iterations; float steps; a
// failed step leaves the state as it was.
#include <catch2/catch.hpp>
#include <cmath>
#include <kinegen/simulator.hpp>

#include "four_bar_spring.hpp"
#include "pendulum.hpp"

namespace {

namespace km = kinegen::models;
constexpr double kPi = 3.14159265358979323846;
constexpr double kEllipticKHalf = 1.8540746773013719;  // K(m = 1/2)

// The pendulum's energy about the pivot (0 when released from horizontal at rest).
template <class T>
double pendulum_energy(const kinegen::Simulator<km::pendulum, T>& sim) {
  const km::pendulum::Params p{};
  const double inertia = p.m * 4 * p.a * p.a / 12 + p.m * p.a * p.a;
  const double w = sim.zd()[0], theta = sim.z()[0];
  return 0.5 * inertia * w * w + p.m * p.g * p.a * std::sin(theta);
}

// Theta at half the period, in n steps of the integrator.
template <class T>
double half_period_theta(kinegen::Integrator integrator, int n, double* worst_energy) {
  const km::pendulum::Params p{};
  const double inertia = p.m * 4 * p.a * p.a / 12 + p.m * p.a * p.a;
  const double half = 2 * std::sqrt(inertia / (p.m * p.g * p.a)) * kEllipticKHalf;
  kinegen::SimulatorOptions o;
  o.integrator = integrator;
  kinegen::Simulator<km::pendulum, T> sim(p, o);
  const T z[] = {T(0)}, zd[] = {T(0)};
  REQUIRE(sim.reset(T(0), z, zd));
  *worst_energy = 0;
  for (int i = 0; i < n; ++i) {
    const kinegen::Result r = sim.step(T(half / n));
    REQUIRE(r);
    *worst_energy = std::max(*worst_energy, std::abs(pendulum_energy(sim)));
  }
  CHECK(double(sim.time()) == Approx(half).epsilon(1e-6));
  return double(sim.z()[0]);
}

}  // namespace

TEST_CASE("Simulator: the pendulum reaches the other horizontal at half its period",
          "[simulator]") {
  const km::pendulum::Params p{};
  const double energy_scale = p.m * p.g * p.a;
  double energy = 0;
  const double rk4 = half_period_theta<double>(kinegen::Integrator::kRungeKutta4, 2000, &energy);
  CHECK(std::abs(rk4 + kPi) < 1e-6);  // the turning point: theta is flat in t there
  CHECK(energy < 1e-10 * energy_scale);
  const double implicit = half_period_theta<double>(kinegen::Integrator::kImplicit, 2000, &energy);
  CHECK(std::abs(implicit + kPi) < 2e-3);
  CHECK(energy < 1e-4 * energy_scale);  // L-stable: it loses a little, never gains
  const double single = half_period_theta<float>(kinegen::Integrator::kRungeKutta4, 500, &energy);
  CHECK(std::abs(single + kPi) < 2e-3);
  // The implicit step's Newton tolerance follows the scalar (float: 3.1e-5).
  const double single_implicit =
      half_period_theta<float>(kinegen::Integrator::kImplicit, 2000, &energy);
  CHECK(std::abs(single_implicit + kPi) < 5e-3);
}

TEST_CASE("Simulator: the implicit step on exact Jacobians agrees with RK4 on the spring four-bar",
          "[simulator]") {
  using M = km::four_bar_spring;
  static_assert(kinegen::Simulator<M>::kExactJacobians);
  kinegen::SimulatorOptions o;
  kinegen::Simulator<M> explicit_sim(M::Params{}, o);
  o.integrator = kinegen::Integrator::kImplicit;
  kinegen::Simulator<M> implicit_sim(M::Params{}, o);
  const double z[] = {4.0}, zd[] = {0.0};
  REQUIRE(explicit_sim.reset(0, z, zd));
  REQUIRE(implicit_sim.reset(0, z, zd));
  for (int i = 0; i < 400; ++i) {
    REQUIRE(explicit_sim.step(1e-4));
    REQUIRE(implicit_sim.step(1e-4));
    CHECK(implicit_sim.newton_iterations() <= 6);  // both stages
  }
  CHECK(implicit_sim.z()[0] == Approx(explicit_sim.z()[0]).epsilon(1e-5));
  CHECK(implicit_sim.zd()[0] == Approx(explicit_sim.zd()[0]).epsilon(1e-3).margin(1e-3));
  // A step that fails leaves the state, q and the accelerations as they were.
  const double before = explicit_sim.z()[0], q5 = explicit_sim.q()[5], t = explicit_sim.time();
  explicit_sim.params().k = std::numeric_limits<double>::quiet_NaN();
  CHECK_FALSE(explicit_sim.step(1e-4));
  CHECK(explicit_sim.z()[0] == before);
  CHECK(explicit_sim.q()[5] == q5);
  CHECK(explicit_sim.time() == t);
}

TEST_CASE("the header's own step_rk4 and step_implicit (no runtime) reach the closed form",
          "[simulator]") {
  using M = km::pendulum;
  const M::Params p{};
  const double inertia = p.m * 4 * p.a * p.a / 12 + p.m * p.a * p.a;
  const double half = 2 * std::sqrt(inertia / (p.m * p.g * p.a)) * kEllipticKHalf;
  for (const bool implicit : {false, true}) {
    M::DynamicsWork<double> w;
    M::JacobianWork<double> j;
    double z[] = {0}, zd[] = {0}, t = 0;
    const int n = 2000;
    for (int i = 0; i < n; ++i) {
      const auto r = implicit ? M::step_implicit(z, zd, t, half / n, p, M::BlockOptions{}, w, j)
                              : M::step_rk4(z, zd, t, half / n, p, M::BlockOptions{}, w);
      REQUIRE(r.status == 0);
    }
    CHECK(t == Approx(half).epsilon(1e-12));
    CHECK(std::abs(z[0] + kPi) < (implicit ? 2e-3 : 1e-6));
  }
}
