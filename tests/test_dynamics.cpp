// Forward dynamics in minimal coordinates against independent truths: a pendulum's
// half period against the elliptic-integral closed form, its acceleration against
// I theta'' = -m g a cos(theta), B = dq/dz against differences of solved positions, the
// reduced mass of a four-bar against its kinetic energy, and the energy balance.
#include <catch2/catch.hpp>

#include <cmath>

#include "kinegen/codegen/analysis/dynamics.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/simulate.hpp"

namespace kc = kinegen::codegen;

namespace {

std::unique_ptr<kc::CompiledModel> compile(const std::string& yaml) {
  kc::BuildOptions build;
  build.free_as_state = true;
  kc::Mechanism m = kc::parse_mechanism(yaml, "test.yaml");
  return kc::CompiledModel::from_mechanism(std::move(m), {}, build);
}

// K(m) = pi / (2 AGM(1, sqrt(1 - m))), the complete elliptic integral of the first kind in
// the parameter m, by the arithmetic-geometric mean (quadratic convergence).
double elliptic_k(double m) {
  long double a = 1, b = std::sqrt(1.0L - m);
  for (int k = 0; k < 10; ++k) {
    const long double an = (a + b) / 2;
    b = std::sqrt(a * b);
    a = an;
  }
  return static_cast<double>(3.14159265358979323846264338327950288L / (2 * a));
}

const char* const kPendulum = R"(
name: pendulum
parameters: {m: 1.5, a: 0.4, g: 9.81}
bodies:
  - {name: rod, q0: [0, 0, 0], mass: m, inertia: "m*(2*a)^2/12", com: [a, 0]}
joints:
  - {type: revolute, i: ground, j: rod, si: [0, 0], sj: [0, 0]}
free:
  - {type: absolute_angle, name: theta, body: rod, value0: 0}
gravity: [0, -g]
stop_when: theta.v
)";

// A four-bar with a free crank under gravity: frames at each link's first pin.
const char* const kFourBar = R"(
name: four_bar_free
bodies:
  - {name: crank, q0: [0, 0, 1.2], mass: 1, inertia: 0.08, com: [0.5, 0]}
  - {name: coupler, q0: [0.36, 0.93, -0.2], mass: 2, inertia: 0.6, com: [1.5, 0.1]}
  - {name: rocker, q0: [4, 0, 1.9], mass: 1.5, inertia: 0.4, com: [1.25, 0]}
joints:
  - {type: revolute, i: ground, j: crank, si: [0, 0], sj: [0, 0]}
  - {type: revolute, i: crank, j: coupler, si: [1, 0], sj: [0, 0]}
  - {type: revolute, i: coupler, j: rocker, si: [3.5, 0], sj: [2.5, 0]}
  - {type: revolute, i: ground, j: rocker, si: [4, 0], sj: [0, 0]}
free:
  - {type: absolute_angle, name: theta, body: crank, v0: 2}
gravity: [0, -9.81]
)";

}  // namespace

TEST_CASE("a pendulum's acceleration is -m g a cos(theta) / I about the pivot", "[dynamics]") {
  const auto model = compile(kPendulum);
  const kc::ForceModel forces = kc::derive_forces(*model);
  kc::ReducedDynamics dyn(*model, forces, 0);
  REQUIRE(dyn.nf() == 1);
  const double m = 1.5, a = 0.4, g = 9.81, inertia = m * (2 * a) * (2 * a) / 12 + m * a * a;
  for (double theta : {0.0, -0.7, -2.0, 1.1}) {
    for (double omega : {0.0, 3.0}) {
      kc::MotionState s;
      REQUIRE(dyn.evaluate(0, &theta, &omega, s));
      CHECK(s.zdd[0] == Approx(-m * g * a * std::cos(theta) / inertia).epsilon(1e-13));
      CHECK(s.q[2] == Approx(theta).margin(1e-14));
      CHECK(s.qdd[2] == Approx(s.zdd[0]).epsilon(1e-14));
      const kc::Energy e = dyn.energy(s);
      CHECK(e.kinetic == Approx(0.5 * inertia * omega * omega).epsilon(1e-13));
      CHECK(e.potential == Approx(m * g * a * std::sin(theta)).margin(1e-13));
      CHECK(e.power == 0);
    }
  }
}

TEST_CASE("a pendulum released from horizontal swings in the elliptic-integral half period",
          "[dynamics]") {
  const auto model = compile(kPendulum);
  const kc::ForceModel forces = kc::derive_forces(*model);
  kc::SimulateOptions o;
  o.rtol = 1e-12;
  o.atol = 1e-14;
  std::vector<kc::SimulatedRow> rows;
  kc::run_simulation(*model, forces, {0, 3, 3}, [&](const kc::SimulatedRow& r) { rows.push_back(r); },
                     o);
  // theta.v crosses 0 from below at the far end of the swing, half a period after release.
  const double m = 1.5, a = 0.4, g = 9.81, inertia = m * (2 * a) * (2 * a) / 12 + m * a * a;
  const double period = 4 * std::sqrt(inertia / (m * g * a)) * elliptic_k(0.5);
  REQUIRE(rows.size() == 2);  // t0, and the root (before the first grid time)
  CHECK(std::abs(rows.back().state.t - period / 2) < 1e-9 * period);
  CHECK(rows.back().z[0] == Approx(-M_PI).epsilon(1e-9));
  for (const auto& r : rows) CHECK(std::abs(r.balance) < 1e-8 * m * g * a);
}

TEST_CASE("B = dq/dz of a four-bar matches differences of solved positions, and its reduced "
          "mass is its kinetic energy's",
          "[dynamics]") {
  const auto model = compile(kFourBar);
  const kc::ForceModel forces = kc::derive_forces(*model);
  kc::ReducedDynamics dyn(*model, forces, 0);
  const double theta = dyn.initial().z[0], omega = 2;
  kc::MotionState s, plus, minus;
  const double h = 1e-6, zero = 0;
  REQUIRE(dyn.evaluate(0, &theta, &omega, s));
  const Eigen::MatrixXd b = dyn.b();
  const double tp = theta + h, tm = theta - h;
  REQUIRE(dyn.evaluate(0, &tp, &zero, plus));
  REQUIRE(dyn.evaluate(0, &tm, &zero, minus));
  const Eigen::VectorXd diff = (plus.q - minus.q) / (2 * h);
  CHECK((diff - b.col(0)).cwiseAbs().maxCoeff() < 1e-8);
  // qd = B zd (no rheonomic drivers); kinetic energy = 1/2 zd M_z zd.
  REQUIRE(dyn.evaluate(0, &theta, &omega, s));
  CHECK((s.qd - b.col(0) * omega).cwiseAbs().maxCoeff() < 1e-12);
  // The kinetic energy from each body's centre velocity and spin, written out here.
  const double mass[] = {1, 2, 1.5}, inertia[] = {0.08, 0.6, 0.4};
  const double com[3][2] = {{0.5, 0}, {1.5, 0.1}, {1.25, 0}};
  double kinetic = 0;
  for (int k = 0; k < 3; ++k) {
    const double phi = s.q[3 * k + 2], w = s.qd[3 * k + 2];
    const double ax = std::cos(phi) * com[k][0] - std::sin(phi) * com[k][1];
    const double ay = std::sin(phi) * com[k][0] + std::cos(phi) * com[k][1];
    const double vx = s.qd[3 * k] - w * ay, vy = s.qd[3 * k + 1] + w * ax;
    kinetic += 0.5 * mass[k] * (vx * vx + vy * vy) + 0.5 * inertia[k] * w * w;
  }
  CHECK(dyn.energy(s).kinetic == Approx(kinetic).epsilon(1e-13));
}

TEST_CASE("a four-bar falling under gravity keeps its energy", "[dynamics]") {
  const auto model = compile(kFourBar);
  const kc::ForceModel forces = kc::derive_forces(*model);
  kc::SimulateOptions o;
  o.rtol = 1e-11;
  o.atol = 1e-13;
  double worst = 0, scale = 0;
  kc::run_simulation(*model, forces, {0, 3, 30},
                     [&](const kc::SimulatedRow& r) {
                       worst = std::max(worst, std::abs(r.balance));
                       scale = std::max(scale, std::abs(r.kinetic));
                     },
                     o);
  REQUIRE(scale > 1);
  CHECK(worst < 1e-8 * scale);
}
