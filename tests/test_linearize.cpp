// Equilibrium, modes and linear models (docs/format.md: `equilibrium`, `modes`, `linearize`)
// against independent truths: a pendulum's small-oscillation frequency sqrt(m g a / I) / (2 pi)
// and its upright equilibrium's negative stiffness; a mass between two springs (equilibrium,
// frequency, damping ratio); a four-bar held by a diagonal spring against a hand-written solve
// of its potential and kinetic energy; the cart-pole's A and B against the textbook
// linearization; the exact Jacobians against central differences of the dynamics and against
// the complex step through an independent dense complex evaluation of the reduction
// (docs/format.md: Equations of motion).
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <fstream>
#include <iterator>

#include "kinegen/codegen/analysis/equilibrium.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/linearize.hpp"

namespace kc = kinegen::codegen;

namespace {

constexpr double kPi = 3.14159265358979323846;

std::unique_ptr<kc::CompiledModel> compile(const std::string& yaml) {
  kc::BuildOptions build;
  build.free_as_state = true;
  return kc::CompiledModel::from_mechanism(kc::parse_mechanism(yaml, "test.yaml"), {}, build);
}

// A model, its forces and a Linearizer at t0 = 0.
struct Setup {
  std::unique_ptr<kc::CompiledModel> model;
  kc::ForceModel forces;
  std::unique_ptr<kc::Linearizer> lin;
  explicit Setup(const std::string& yaml) : Setup(compile(yaml)) {}
  explicit Setup(std::unique_ptr<kc::CompiledModel> m)
      : model(std::move(m)),
        forces(kc::derive_forces(*model)),
        lin(std::make_unique<kc::Linearizer>(*model, forces, 0.0)) {}
  kc::OperatingPoint at(const std::vector<double>& z, const std::vector<double>& zd = {},
                        const std::vector<double>& u = {}) const {
    const auto vector = [](const std::vector<double>& v) {
      Eigen::VectorXd out(static_cast<Eigen::Index>(v.size()));
      for (std::size_t k = 0; k < v.size(); ++k) out[static_cast<Eigen::Index>(k)] = v[k];
      return out;
    };
    kc::OperatingPoint p = lin->initial();
    p.z = vector(z);
    if (!zd.empty()) p.zd = vector(zd);
    if (!u.empty()) p.u = vector(u);
    return p;
  }
};

// examples/dynamics/NAME.yaml, its free coordinates as states.
std::unique_ptr<kc::CompiledModel> example(const std::string& name) {
  kc::BuildOptions build;
  build.free_as_state = true;
  return kc::CompiledModel::from_file(
      std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/" + name + ".yaml", {}, build);
}

std::string pendulum(double value0) {
  return R"(
name: pendulum
parameters: {m: 1.5, a: 0.4, g: 9.81}
bodies:
  - {name: rod, q0: [0, 0, 0], mass: m, inertia: "m*(2*a)^2/12", com: [a, 0]}
joints:
  - {type: revolute, i: ground, j: rod}
free:
  - {type: absolute_angle, name: theta, body: rod, value0: )" +
         std::to_string(value0) + R"(}
gravity: [0, -g]
)";
}

// A block on a horizontal rail between two springs anchored at x = -L1 and x = L2.
std::string mass_on_springs(double damping) {
  return R"(
name: mass_on_springs
parameters: {m: 2.5, k1: 300, k2: 500, L1: 1.0, L2: 1.5, l1: 0.8, l2: 1.1, c: )" +
         std::to_string(damping) + R"(}
bodies:
  - {name: block, q0: [0, 0, 0], mass: m, inertia: 0.1}
joints:
  - {type: translational, i: ground, j: block, vi: [1, 0]}
free:
  - {type: absolute_x, name: x, body: block, value0: 0}
forces:
  - {type: spring_damper, i: ground, j: block, si: ["-L1", 0], stiffness: k1, length0: l1,
     damping: c}
  - {type: spring_damper, i: ground, j: block, si: [L2, 0], stiffness: k2, length0: l2}
)";
}

}  // namespace

TEST_CASE("a pendulum swings at sqrt(m g a / I) / (2 pi) about its lowest position",
          "[linearize]") {
  const double m = 1.5, a = 0.4, g = 9.81, inertia = m * (2 * a) * (2 * a) / 12 + m * a * a;
  const double f = std::sqrt(m * g * a / inertia) / (2 * kPi);
  for (double value0 : {-1.2, 0.0}) {  // near the bottom, and at horizontal (K_z = 0 there)
    INFO("value0 " << value0);
    Setup s(pendulum(value0));
    const kc::Equilibrium e = kc::find_equilibrium(*s.lin, s.lin->initial());
    CHECK(e.at.z[0] == Approx(-kPi / 2).margin(1e-14));
    CHECK(e.stiffness.stability == kc::Stability::kStable);
    CHECK(e.stiffness.mass(0, 0) == Approx(inertia).epsilon(1e-14));
    CHECK(e.stiffness.stiffness(0, 0) == Approx(m * g * a).epsilon(1e-13));
    // The pin carries the weight at rest.
    CHECK(std::abs(e.force[0]) < 1e-14 * m * g * a);
    const kc::ModalAnalysis modes = kc::modal_analysis(*s.lin, e.at);
    REQUIRE(modes.modes.size() == 1);
    CHECK_FALSE(modes.damped);
    CHECK(std::abs(modes.modes[0].frequency / f - 1) < 1e-12);
    // The shape: dz = 1, dq the rod's angle (its frame is at the pivot: no x, y).
    CHECK(modes.modes[0].dq[2] == 1);
    CHECK(std::abs(modes.modes[0].dq[0]) < 1e-15);
  }
}

TEST_CASE("the upright pendulum is an unstable equilibrium, along theta", "[linearize]") {
  const double m = 1.5, a = 0.4, g = 9.81, inertia = m * (2 * a) * (2 * a) / 12 + m * a * a;
  Setup s(pendulum(1.4));
  const kc::Equilibrium e =
      kc::find_equilibrium(*s.lin, s.lin->initial(), kc::EquilibriumSearch::kNearest);
  CHECK(e.at.z[0] == Approx(kPi / 2).margin(1e-14));
  CHECK(e.stiffness.stability == kc::Stability::kUnstable);
  REQUIRE(e.stiffness.unstable == std::vector<std::string>{"theta"});
  CHECK(e.stiffness.eigenvalues[0] == Approx(-m * g * a / inertia).epsilon(1e-13));
  const kc::ModalAnalysis modes = kc::modal_analysis(*s.lin, e.at);
  CHECK(modes.modes[0].kind == kc::Stability::kUnstable);
  CHECK(modes.modes[0].frequency == 0);
}

TEST_CASE("released from near upright, the pendulum comes to rest at the bottom", "[linearize]") {
  // From 1.4 rad gravity turns it down through 0 to -pi/2; from exactly upright (pi/2 in
  // double, an equilibrium to rounding) it is left along +theta and falls over the top to
  // 3 pi/2.
  for (const auto& [value0, rest] : {std::pair{1.4, -kPi / 2}, std::pair{kPi / 2, 3 * kPi / 2}}) {
    INFO("value0 " << value0);
    Setup s(pendulum(0));
    const kc::Equilibrium e = kc::find_equilibrium(*s.lin, s.at({value0}));
    CHECK(e.at.z[0] == Approx(rest).margin(1e-14));
    CHECK(e.stiffness.stability == kc::Stability::kStable);
    CHECK(e.left_start == (value0 == kPi / 2));
    CHECK(e.flow_steps > 0);
    // At rest to rounding: |B^T Q^A| within the bound Newton stops at.
    CHECK(std::abs(e.force[0]) <= e.bound[0]);
    CHECK(e.bound[0] < 1e-13 * 1.5 * 9.81 * 0.4);
  }
}

TEST_CASE("a mass between two springs rests where they balance and swings at sqrt(k / m)",
          "[linearize]") {
  const double m = 2.5, k1 = 300, k2 = 500, L1 = 1.0, L2 = 1.5, l1 = 0.8, l2 = 1.1;
  const double x = (k2 * (L2 - l2) - k1 * (L1 - l1)) / (k1 + k2), k = k1 + k2;
  {
    Setup s(mass_on_springs(0));
    const kc::Equilibrium e = kc::find_equilibrium(*s.lin, s.lin->initial());
    CHECK(e.at.z[0] == Approx(x).margin(1e-15));
    CHECK(e.state.q[0] == Approx(x).margin(1e-15));
    CHECK(e.stiffness.stiffness(0, 0) == Approx(k).epsilon(1e-13));
    CHECK(e.stiffness.mass(0, 0) == Approx(m).epsilon(1e-15));
    const kc::ModalAnalysis modes = kc::modal_analysis(*s.lin, e.at);
    CHECK(std::abs(modes.modes[0].frequency / (std::sqrt(k / m) / (2 * kPi)) - 1) < 1e-13);
  }
  {
    // A damper beside spring 1: zeta = c / (2 sqrt(k m)), f_d = f sqrt(1 - zeta^2).
    const double c = 9.0, zeta = c / (2 * std::sqrt(k * m));
    Setup s(mass_on_springs(c));
    const kc::Equilibrium e = kc::find_equilibrium(*s.lin, s.lin->initial());
    CHECK(e.at.z[0] == Approx(x).margin(1e-15));
    const kc::ModalAnalysis modes = kc::modal_analysis(*s.lin, e.at);
    REQUIRE(modes.damped);
    CHECK(modes.stiffness.damping(0, 0) == Approx(c).epsilon(1e-13));
    const double f = std::sqrt(k / m) / (2 * kPi);
    CHECK(std::abs(modes.modes[0].frequency / f - 1) < 1e-12);
    CHECK(std::abs(modes.modes[0].damping_ratio / zeta - 1) < 1e-12);
    CHECK(std::abs(modes.modes[0].damped_frequency / (f * std::sqrt(1 - zeta * zeta)) - 1) < 1e-12);
    // The linear model: x'' = -(k x' + c x'')/m about the rest position.
    const kc::LinearModel l = kc::linearize(*s.lin, e.at);
    CHECK(l.a(1, 0) == Approx(-k / m).epsilon(1e-13));
    CHECK(l.a(1, 1) == Approx(-c / m).epsilon(1e-13));
    CHECK(l.b.cols() == 0);  // no run-time inputs: B is empty
  }
}

namespace {

// The four-bar of examples/dynamics/four_bar_spring.yaml by hand, in T = double or complex
// (for the complex step): from the crank angle th, A = a (cos th, sin th); B where the circles
// about A (radius b) and O4 = (d, 0) (radius c) meet, on side `side` of A -> O4; the coupler's
// direction e = (B - A) / b and the rocker's r = (B - O4) / c.
template <class T>
struct FourBar {
  T ax, ay, bx, by, ex, ey, rx, ry;
};
constexpr double kA = 0.1, kB = 0.35, kC = 0.25, kD = 0.3, kK = 400, kL0 = 0.2, kG = 9.81;
constexpr double kM1 = 0.4, kJ1 = 0.0004, kM2 = 1.2, kJ2 = 0.012, kM3 = 0.9, kJ3 = 0.005;

template <class T>
FourBar<T> four_bar(T th, double side) {
  using std::cos, std::sin, std::sqrt;
  FourBar<T> s;
  s.ax = kA * cos(th);
  s.ay = kA * sin(th);
  const T dx = kD - s.ax, dy = -s.ay, l = sqrt(dx * dx + dy * dy);
  const T p = (kB * kB - kC * kC + l * l) / (2.0 * l), h = sqrt(kB * kB - p * p);
  const T ux = dx / l, uy = dy / l;
  s.bx = s.ax + p * ux - side * h * uy;
  s.by = s.ay + p * uy + side * h * ux;
  s.ex = (s.bx - s.ax) / kB;
  s.ey = (s.by - s.ay) / kB;
  s.rx = (s.bx - kD) / kC;
  s.ry = s.by / kC;
  return s;
}

// Potential: the weights (centres of mass at a/2 on the crank, (b/2, 0.02) on the coupler,
// c/2 on the rocker) and the spring from the ground pivot O2 to B.
template <class T>
T potential(T th, double side) {
  using std::sqrt;
  const FourBar<T> s = four_bar(th, side);
  const T y1 = 0.5 * s.ay, y2 = s.ay + kB / 2 * s.ey + 0.02 * s.ex, y3 = kC / 2 * s.ry;
  const T stretch = sqrt(s.bx * s.bx + s.by * s.by) - kL0;
  return kG * (kM1 * y1 + kM2 * y2 + kM3 * y3) + kK / 2 * stretch * stretch;
}

// d/dth by the complex step.
template <class F>
double derivative(F f, double th) {
  const double h = 1e-30;
  return std::imag(f(std::complex<double>(th, h))) / h;
}

double v_prime(double th, double side) {
  return derivative([&](std::complex<double> x) { return potential(x, side); }, th);
}

// V'' by Richardson-extrapolated central differences of the exact V'.
double v_second(double th, double side) {
  const auto d = [&](double h) {
    return (v_prime(th + h, side) - v_prime(th - h, side)) / (2 * h);
  };
  return (4 * d(5e-4) - d(1e-3)) / 3;
}

// The kinetic energy's coefficient: T = 1/2 M(th) th'^2.
double reduced_mass(double th, double side) {
  using C = std::complex<double>;
  const auto part = [&](auto get) {
    return derivative([&](C x) { return get(four_bar(x, side)); }, th);
  };
  const double v1x = -0.5 * kA * std::sin(th), v1y = 0.5 * kA * std::cos(th);
  const double ex = part([](const FourBar<C>& s) { return s.ex; });
  const double ey = part([](const FourBar<C>& s) { return s.ey; });
  const double rx = part([](const FourBar<C>& s) { return s.rx; });
  const double ry = part([](const FourBar<C>& s) { return s.ry; });
  const double ax = part([](const FourBar<C>& s) { return s.ax; });
  const double ay = part([](const FourBar<C>& s) { return s.ay; });
  const FourBar<double> s = four_bar(th, side);
  const double w2 = s.ex * ey - s.ey * ex, w3 = s.rx * ry - s.ry * rx;
  const double v2x = ax + kB / 2 * ex - 0.02 * ey, v2y = ay + kB / 2 * ey + 0.02 * ex;
  const double v3x = kC / 2 * rx, v3y = kC / 2 * ry;
  return kM1 * (v1x * v1x + v1y * v1y) + kJ1 + kM2 * (v2x * v2x + v2y * v2y) + kJ2 * w2 * w2 +
         kM3 * (v3x * v3x + v3y * v3y) + kJ3 * w3 * w3;
}

}  // namespace

TEST_CASE("a four-bar held by a diagonal spring: its rest and frequency by hand", "[linearize]") {
  const Setup s(example("four_bar_spring"));
  kc::Linearizer& lin = *s.lin;
  const kc::Equilibrium e = kc::find_equilibrium(lin, lin.initial());
  // The branch kinegen assembled on (the side of A -> O4 its B lies), from its own B.
  const Eigen::VectorXd& q = e.state.q;
  const double bx = q[3] + kB * std::cos(q[5]), by = q[4] + kB * std::sin(q[5]);
  const FourBar<double> plus = four_bar(e.at.z[0], 1.0);
  const double side = std::hypot(plus.bx - bx, plus.by - by) < 1e-6 ? 1.0 : -1.0;
  // The rest position by hand: V'(th) = 0 by Newton from value0.
  double th = 4.3;
  for (int it = 0; it < 30; ++it) th -= v_prime(th, side) / v_second(th, side);
  REQUIRE(std::abs(v_prime(th, side)) < 1e-12);
  CHECK(e.at.z[0] == Approx(th).margin(1e-11));
  const FourBar<double> hand = four_bar(th, side);
  CHECK(bx == Approx(hand.bx).margin(1e-11));
  CHECK(by == Approx(hand.by).margin(1e-11));
  // K_z = V'' and M_z = M(th); the frequency sqrt(V'' / M) / (2 pi).
  REQUIRE(e.stiffness.stability == kc::Stability::kStable);
  CHECK(e.stiffness.stiffness(0, 0) == Approx(v_second(th, side)).epsilon(1e-9));
  CHECK(e.stiffness.mass(0, 0) == Approx(reduced_mass(th, side)).epsilon(1e-13));
  const kc::ModalAnalysis modes = kc::modal_analysis(lin, e.at);
  const double f = std::sqrt(v_second(th, side) / reduced_mass(th, side)) / (2 * kPi);
  CHECK(std::abs(modes.modes[0].frequency / f - 1) < 1e-9);
}

TEST_CASE(
    "the four-bar with a spring released rests at the minimum downhill; Newton's nearest "
    "root is the maximum uphill",
    "[linearize][equilibrium]") {
  const Setup s(example("four_bar_spring"));
  kc::Linearizer& lin = *s.lin;
  // Either side of the potential's maximum near 0.61 rad: from 0.7 the crank is released
  // upwards (to the rest near 4.27 rad), from 0.5 downwards (to the same rest a turn lower);
  // Newton from either goes to the maximum.
  for (const double start : {0.7, 0.5}) {
    INFO("from " << start);
    const kc::Equilibrium rest = kc::find_equilibrium(lin, s.at({start}));
    const kc::Equilibrium nearest =
        kc::find_equilibrium(lin, s.at({start}), kc::EquilibriumSearch::kNearest);
    // The branch, from kinegen's own B (as above).
    const Eigen::VectorXd& q = rest.state.q;
    const double bx = q[3] + kB * std::cos(q[5]), by = q[4] + kB * std::sin(q[5]);
    const FourBar<double> plus = four_bar(rest.at.z[0], 1.0);
    const double side = std::hypot(plus.bx - bx, plus.by - by) < 1e-6 ? 1.0 : -1.0;
    // By hand: the overdamped flow M dth/ds = -V' turns the crank downhill from the start to
    // the first zero of V' that way, a minimum of V; uphill the first zero is a maximum.
    const auto first_zero = [&](double from, double step) {
      double a = from, b = from + step;
      while (v_prime(a, side) * v_prime(b, side) > 0) a = b, b += step;
      for (int it = 0; it < 200; ++it) {
        const double mid = (a + b) / 2;
        if (mid == a || mid == b) break;
        (v_prime(a, side) * v_prime(mid, side) <= 0 ? b : a) = mid;
      }
      return (a + b) / 2;
    };
    const double downhill = v_prime(start, side) > 0 ? -1e-3 : 1e-3;
    const double bottom = first_zero(start, downhill), top = first_zero(start, -downhill);
    REQUIRE(v_second(bottom, side) > 0);
    REQUIRE(v_second(top, side) < 0);
    CHECK(rest.at.z[0] == Approx(bottom).margin(1e-12));
    CHECK(rest.stiffness.stability == kc::Stability::kStable);
    CHECK(rest.flow_steps > 0);
    CHECK(std::abs(rest.force[0]) <= rest.bound[0]);
    CHECK(nearest.at.z[0] == Approx(top).margin(1e-12));
    CHECK(nearest.stiffness.stability == kc::Stability::kUnstable);
    CHECK(nearest.flow_steps == 0);
    CHECK(std::abs(nearest.force[0]) <= nearest.bound[0]);
  }
}

TEST_CASE("the cart-pole's A and B are the textbook linearization about upright", "[linearize]") {
  const Setup s(example("cart_pole"));
  kc::Linearizer& lin = *s.lin;
  REQUIRE(kc::input_names(s.model->mechanism()) == std::vector<std::string>{"push_x"});
  const kc::LinearModel l = kc::linearize(lin, lin.initial());
  // z = (x, phi), phi from the rail; upright phi = pi/2. The pole's centre of mass
  // (x + a cos phi, a sin phi) moves at (x' - a phi', 0) there: T = 1/2 M x'^2 +
  // 1/2 m (x' - a phi')^2 + 1/2 I_c phi'^2, V = m g a sin phi ~ m g a (1 - psi^2 / 2).
  const double cart = 1.0, mp = 0.2, a = 0.3, g = 9.81, ic = mp * (2 * a) * (2 * a) / 12;
  Eigen::Matrix2d mz, kz;
  mz << cart + mp, -mp * a, -mp * a, mp * a * a + ic;
  kz << 0, 0, 0, -mp * g * a;
  Eigen::Matrix4d a_ref = Eigen::Matrix4d::Zero();
  a_ref.topRightCorner<2, 2>().setIdentity();
  a_ref.bottomLeftCorner<2, 2>() = -mz.inverse() * kz;
  Eigen::Vector4d b_ref = Eigen::Vector4d::Zero();
  b_ref.tail<2>() = mz.inverse() * Eigen::Vector2d(1, 0);
  CHECK((l.a - a_ref).cwiseAbs().maxCoeff() < 1e-12 * a_ref.cwiseAbs().maxCoeff());
  REQUIRE(l.b.cols() == 1);
  CHECK((l.b - b_ref).cwiseAbs().maxCoeff() < 1e-12 * b_ref.cwiseAbs().maxCoeff());
  CHECK(l.xdot.cwiseAbs().maxCoeff() < 1e-14);  // upright at rest: an equilibrium
  CHECK(l.states == std::vector<std::string>{"x", "phi", "x.v", "phi.v"});
}

TEST_CASE("the double cart-pole's A and B are the Lagrangian linearization about upright",
          "[linearize]") {
  const Setup s(example("double_cart_pole"));
  const kc::LinearModel l = kc::linearize(*s.lin, s.lin->initial());
  // z = (x, phi1, phi2), absolute angles from the rail, upright pi/2 + psi_i. The poles'
  // centres of mass move at (x' - l1/2 psi1', 0) and (x' - l1 psi1' - l2/2 psi2', 0) there:
  // T = 1/2 M x'^2 + 1/2 m1 (x' - l1/2 psi1')^2 + 1/2 I1 psi1'^2 + 1/2 m2 (x' - l1 psi1' -
  // l2/2 psi2')^2 + 1/2 I2 psi2'^2 and V = m1 g l1/2 cos psi1 + m2 g (l1 cos psi1 + l2/2 cos
  // psi2), I_i = m_i l_i^2 / 12 about the centre.
  const double cart = 1.0, m1 = 0.3, m2 = 0.2, l1 = 0.6, l2 = 0.4, g = 9.81;
  const double i1 = m1 * l1 * l1 / 12, i2 = m2 * l2 * l2 / 12;
  Eigen::Matrix3d mz, kz;
  mz << cart + m1 + m2, -(m1 / 2 + m2) * l1, -m2 * l2 / 2,                  //
      -(m1 / 2 + m2) * l1, (m1 / 4 + m2) * l1 * l1 + i1, m2 * l1 * l2 / 2,  //
      -m2 * l2 / 2, m2 * l1 * l2 / 2, m2 * l2 * l2 / 4 + i2;
  kz << 0, 0, 0, 0, -(m1 / 2 + m2) * g * l1, 0, 0, 0, -m2 * g * l2 / 2;
  Eigen::Matrix<double, 6, 6> a_ref = Eigen::Matrix<double, 6, 6>::Zero();
  a_ref.topRightCorner<3, 3>().setIdentity();
  a_ref.bottomLeftCorner<3, 3>() = -mz.inverse() * kz;
  Eigen::Matrix<double, 6, 1> b_ref = Eigen::Matrix<double, 6, 1>::Zero();
  b_ref.tail<3>() = mz.inverse() * Eigen::Vector3d(1, 0, 0);
  CHECK((l.a - a_ref).cwiseAbs().maxCoeff() < 1e-12 * a_ref.cwiseAbs().maxCoeff());
  REQUIRE(l.b.cols() == 1);
  CHECK((l.b - b_ref).cwiseAbs().maxCoeff() < 1e-12 * b_ref.cwiseAbs().maxCoeff());
  CHECK(l.xdot.cwiseAbs().maxCoeff() < 1e-13);
}

namespace {

using C = std::complex<double>;
using CL = std::complex<long double>;

// zdd at (t, z, zd, u) in complex arithmetic (C, or CL for a reference beyond double's
// rounding), by an independent dense implementation of the reduction of docs/format.md's
// "Equations of motion" on the model's first-order programs: Newton on all of Phi from the
// real solution, qd and c = qdd(zdd = 0) from Phi_q, B from Phi_q B = E (the free rows, whose
// equations are quantity - z), M B as the inertia forces of accelerations B, and
// (B^T M B) zdd = B^T (Q^A + inertia forces at c).
template <class C>
Eigen::Matrix<C, -1, 1> complex_zdd(const kc::CompiledModel& model, const kc::ForceModel& forces,
                                    double t, const Eigen::Matrix<C, -1, 1>& z,
                                    const Eigen::Matrix<C, -1, 1>& zd,
                                    const Eigen::Matrix<C, -1, 1>& u,
                                    const Eigen::VectorXd& q_start) {
  using V = Eigen::Matrix<C, -1, 1>;
  using M = Eigen::Matrix<C, -1, -1>;
  const kc::Mechanism& m = model.mechanism();
  const int nq = model.nq(), nf = static_cast<int>(z.size());
  const int nb = static_cast<int>(m.bodies.size());
  std::vector<C> inputs(m.input_slots(), C(0));
  const std::vector<int> free = m.free_drivers();
  std::vector<int> rows;
  for (int k = 0; k < nf; ++k) {
    inputs[3 * free[k]] = z[k];
    inputs[3 * free[k] + 1] = zd[k];
    int row = 0;
    for (int c = 0; c < static_cast<int>(m.joints.size()) + free[k]; ++c)
      row += m.constraints()[c]->equation_count();
    rows.push_back(row);
  }
  const auto run = kc::run_inputs(m);
  for (std::size_t k = 0; k < run.size(); ++k) inputs[run[k].slot] = u[k];
  kc::ModelEvaluator<C> ev(model);
  ev.set_inputs(inputs.data());
  V q = q_start.template cast<C>(), phi(nq);
  M jac(nq, nq);
  for (int it = 0; it < 8; ++it) {
    ev.phi(q.data(), C(t), phi.data());
    jac.setZero();
    ev.jacobian(q.data(), C(t), jac);
    q -= jac.partialPivLu().solve(phi);
  }
  jac.setZero();
  ev.jacobian(q.data(), C(t), jac);
  const Eigen::PartialPivLU<M> lu(jac);
  V nu(nq), gamma(nq);
  ev.nu(q.data(), C(t), nu.data());
  const V qd = lu.solve(nu);
  ev.gamma(q.data(), qd.data(), C(t), gamma.data());
  const V c = lu.solve(gamma);
  M e = M::Zero(nq, nf);
  for (int k = 0; k < nf; ++k) e(rows[k], k) = C(1);
  const M b = lu.solve(e);
  const kc::Program applied = kc::lower(forces.applied, model.symbols());
  kc::ProgramEvaluator<C> qa(applied);
  qa.set_inputs(inputs.data());
  std::vector<C> params;
  for (double v : model.params()) params.push_back(C(v));
  V g(nq);
  qa.run(q.data(), qd.data(), C(t), params.data(), g.data());
  kc::ForceData<C> d;
  for (int k = 0; k < nb; ++k) {
    d.mass.push_back(C(forces.numbers.mass[k]));
    d.inertia.push_back(C(forces.numbers.inertia[k]));
    d.com.push_back({C(forces.numbers.com[k][0]), C(forces.numbers.com[k][1])});
  }
  kc::add_inertia_forces(d, nb, q.data(), qd.data(), c.data(), g.data());
  M mb = M::Zero(nq, nf);
  const V still = V::Zero(nq);
  for (int k = 0; k < nf; ++k) {
    const V acc = b.col(k);
    kc::add_inertia_forces(d, nb, q.data(), still.data(), acc.data(), mb.col(k).data());
  }
  mb = -mb;
  return (b.transpose() * mb).lu().solve(b.transpose() * g);
}

struct Jacobians {
  Eigen::MatrixXd d_z, d_zd, d_u;
};

// d(zdd)/d(z, zd, u) by the complex step of complex_zdd in long double (h = 1e-30): a
// reference whose own rounding (1e-19) is far below double's, so that the comparison
// measures the exact Jacobians' error alone.
Jacobians complex_step(const kc::CompiledModel& model, const kc::ForceModel& forces,
                       const kc::OperatingPoint& p, const Eigen::VectorXd& q) {
  const int nf = static_cast<int>(p.z.size()), nu = static_cast<int>(p.u.size());
  const long double h = 1e-30L;
  using V = Eigen::Matrix<CL, -1, 1>;
  Jacobians j{Eigen::MatrixXd(nf, nf), Eigen::MatrixXd(nf, nf), Eigen::MatrixXd(nf, nu)};
  for (int col = 0; col < 2 * nf + nu; ++col) {
    V z = p.z.cast<CL>(), zd = p.zd.cast<CL>(), u = p.u.cast<CL>();
    if (col < nf)
      z[col] += CL(0, h);
    else if (col < 2 * nf)
      zd[col - nf] += CL(0, h);
    else
      u[col - 2 * nf] += CL(0, h);
    const Eigen::VectorXd d =
        (complex_zdd<CL>(model, forces, p.t, z, zd, u, q).imag() / h).template cast<double>();
    (col < nf ? j.d_z.col(col) : col < 2 * nf ? j.d_zd.col(col - nf) : j.d_u.col(col - 2 * nf)) = d;
  }
  return j;
}

// The same by central differences of ReducedDynamics (through the Linearizer), step
// 1e-5 of each state's scale (of 1 for an input).
Jacobians central(kc::Linearizer& lin, const kc::OperatingPoint& p) {
  const int nf = lin.nf(), nu = lin.nu();
  const Eigen::VectorXd s = lin.scales();
  Jacobians j{Eigen::MatrixXd(nf, nf), Eigen::MatrixXd(nf, nf), Eigen::MatrixXd(nf, nu)};
  for (int col = 0; col < 2 * nf + nu; ++col) {
    const double h = 1e-5 * (col < 2 * nf ? s[col % nf] : 1.0);
    Eigen::VectorXd d[2];
    for (int side = 0; side < 2; ++side) {
      kc::OperatingPoint x = p;
      const double step = side == 0 ? h : -h;
      if (col < nf)
        x.z[col] += step;
      else if (col < 2 * nf)
        x.zd[col - nf] += step;
      else
        x.u[col - 2 * nf] += step;
      kc::MotionState st;
      REQUIRE(lin.evaluate(x, st));
      d[side] = st.zdd;
    }
    const Eigen::VectorXd v = (d[0] - d[1]) / (2 * h);
    (col < nf ? j.d_z.col(col) : col < 2 * nf ? j.d_zd.col(col - nf) : j.d_u.col(col - 2 * nf)) = v;
  }
  return j;
}

// The largest difference relative to the size of the linear model: the largest entry of the
// Jacobians, or of the accelerations where they are larger (a Jacobian much smaller than the
// accelerations it differentiates, as a four-bar's far from rest with zdd = 357 rad/s^2 and
// d(zdd)/dz = 5.2 /s^2, is a sum of terms of their size and carries their rounding).
double relative(const Eigen::MatrixXd& got, const Eigen::MatrixXd& want, double scale) {
  if (want.size() == 0) return 0;
  return (got - want).cwiseAbs().maxCoeff() / scale;
}

// A pendulum on a cart whose motion is a run-time input (f: input): d(zdd)/du for the
// driver's value, rate and acceleration; a motor torque on the pendulum as a load's input.
const char* const kShakenPendulum = R"(
name: shaken_pendulum
parameters: {m: 1.0, a: 0.4, g: 9.81}
gravity: [0, -g]
bodies:
  - {name: cart, q0: [0, 0, 0], mass: 2.0, inertia: 0.05}
  - {name: rod, q0: [0, 0, -1.27], mass: m, inertia: "m*(2*a)^2/12", com: [a, 0.05]}
joints:
  - {type: translational, name: rail, i: ground, j: cart, vi: [1, 0.2]}
  - {type: revolute, name: pivot, i: cart, j: rod}
drivers:
  - {type: absolute_x, name: shaker, body: cart, f: input}
free:
  - {type: absolute_angle, name: theta, body: rod, value0: -1.27}
forces:
  - {type: torque, name: motor, body: rod, value: input}
  - {type: rotational_spring_damper, i: cart, j: rod, stiffness: 3, damping: 0.4, angle0: -1}
)";

}  // namespace

TEST_CASE("the exact Jacobians against the complex step and central differences", "[linearize]") {
  struct Case {
    std::string name, yaml;
    std::vector<double> z, zd, u;
  };
  const auto example = [](const std::string& name) {
    std::ifstream in(std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/" + name + ".yaml");
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::vector<Case> cases = {
      {"cart_pole", example("cart_pole"), {0.3, 1.2}, {-0.7, 2.1}, {3.5}},
      {"four_bar_damped", example("four_bar_damped"), {0.7}, {-3.0}, {}},
      {"four_bar_spring", example("four_bar_spring"), {1.5}, {4.0}, {}},
      {"four_bar_spring at rest", example("four_bar_spring"), {4.2666}, {0.0}, {}},
      {"shaken_pendulum", kShakenPendulum, {-0.9}, {1.7}, {0.05, -0.3, 2.0, 0.8}},
  };
  for (const Case& c : cases) {
    INFO(c.name);
    Setup s(c.yaml);
    const kc::OperatingPoint p = s.at(c.z, c.zd, c.u);
    kc::MotionState state;
    Eigen::MatrixXd d_z, d_zd, d_u;
    REQUIRE(s.lin->evaluate(p, state, &d_z, &d_zd, &d_u));
    const Jacobians cs = complex_step(*s.model, s.forces, p, state.q);
    double scale = state.zdd.cwiseAbs().maxCoeff();
    for (const Eigen::MatrixXd* m : {&cs.d_z, &cs.d_zd, &cs.d_u})
      if (m->size()) scale = std::max(scale, m->cwiseAbs().maxCoeff());
    INFO("complex step: " << relative(d_z, cs.d_z, scale) << " " << relative(d_zd, cs.d_zd, scale)
                          << " " << relative(d_u, cs.d_u, scale));
    CHECK(relative(d_z, cs.d_z, scale) < 1e-14);
    CHECK(relative(d_zd, cs.d_zd, scale) < 1e-14);
    CHECK(relative(d_u, cs.d_u, scale) < 1e-14);
    const Jacobians cd = central(*s.lin, p);
    INFO("central: " << relative(d_z, cd.d_z, scale) << " " << relative(d_zd, cd.d_zd, scale) << " "
                     << relative(d_u, cd.d_u, scale));
    CHECK(relative(d_z, cd.d_z, scale) < 1e-7);
    CHECK(relative(d_zd, cd.d_zd, scale) < 1e-7);
    CHECK(relative(d_u, cd.d_u, scale) < 1e-7);
    // The complex evaluation is the same dynamics: its real part is zdd.
    // The solves through the blocks (as generated code) and on one LU of Phi_q agree.
    kc::Linearizer lu(*s.model, s.forces, 0.0, false);
    kc::MotionState lu_state;
    Eigen::MatrixXd lu_z, lu_zd, lu_u;
    REQUIRE(lu.evaluate(p, lu_state, &lu_z, &lu_zd, &lu_u));
    CHECK(relative(lu_z, d_z, scale) < 1e-14);
    CHECK(relative(lu_zd, d_zd, scale) < 1e-14);
    CHECK(relative(lu_u, d_u, scale) < 1e-14);
    const Eigen::VectorXcd z = p.z.cast<C>(), zd = p.zd.cast<C>(), u = p.u.cast<C>();
    CHECK(relative(complex_zdd<C>(*s.model, s.forces, p.t, z, zd, u, state.q).real(), state.zdd,
                   scale) < 1e-13);
  }
}

TEST_CASE("a distance free coordinate moves as its absolute_x twin (dq/dz of |d|^2 - z^2)",
          "[linearize]") {
  // A block on a rail pushed by 3 N, its free coordinate its x, or its distance from the
  // origin (the same quantity where x > 0): zdd = F / m either way, and no stiffness.
  const std::string x = R"(
name: slide
bodies:
  - {name: block, q0: [2, 0, 0], mass: 2.0, inertia: 0.1}
joints:
  - {type: translational, i: ground, j: block, vi: [1, 0]}
free:
  - {type: absolute_x, name: s, body: block, value0: 2, v0: 0.5}
forces:
  - {type: force, body: block, f: [3, 0]}
)";
  std::string d = x;
  d.replace(d.find("absolute_x, name: s, body: block"), 32,
            "distance, name: s, i: ground, j: block");
  for (const std::string& yaml : {x, d}) {
    Setup s(yaml);
    const kc::LinearModel l = kc::linearize(*s.lin, s.at({2.5}, {0.5}));
    CHECK(l.xdot[1] == Approx(1.5).epsilon(1e-15));
    CHECK(std::abs(l.a(1, 0)) < 1e-15);
    CHECK(std::abs(l.a(1, 1)) < 1e-15);
  }
}
