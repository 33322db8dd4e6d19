// Kinetostatics against independent truths: virtual power on a slider-crank, the
// closed form of an accelerating crank under gravity, Newton's and Euler's laws
// for every body from the reported reactions, and the power balance with a spring-damper.
#include <catch2/catch.hpp>

#include <cmath>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "support/run_command.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace kc = kinegen::codegen;

namespace {

struct Solved {
  double t;
  Eigen::VectorXd q, qd, qdd;
  std::vector<double> columns;
  Eigen::VectorXd lambda;
};

std::unique_ptr<kc::CompiledModel> compile(const std::string& yaml) {
  return kc::CompiledModel::from_mechanism(kc::parse_mechanism(yaml, "test.yaml"));
}

kc::Expr num(const std::string& text) { return kc::Expr{text, {}}; }
kc::Vec2 vec(const std::string& x, const std::string& y) { return {num(x), num(y)}; }

std::vector<Solved> solve(const kc::CompiledModel& model, const kc::ForceModel& forces,
                          double t1, int steps) {
  kc::ForceSolver solver(model, forces);
  std::vector<Solved> rows;
  kc::run_analysis(model, {0, t1, steps}, [&](const kc::StateRow& r) {
    Solved s{r.t, r.q, r.qd, r.qdd, {}, {}};
    REQUIRE(solver.solve(r.t, r.q, r.qd, r.qdd, s.columns));
    s.lambda = solver.lambda();
    rows.push_back(std::move(s));
  });
  return rows;
}

Eigen::Vector2d rot(double phi, const Eigen::Vector2d& s) {
  return {std::cos(phi) * s[0] - std::sin(phi) * s[1], std::sin(phi) * s[0] + std::cos(phi) * s[1]};
}
Eigen::Vector2d com_of(const kc::ForceModel& f, int b) {
  return {f.numbers.com[b][0], f.numbers.com[b][1]};
}
double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a[0] * b[1] - a[1] * b[0]; }

}  // namespace

TEST_CASE("forces: virtual power on a slider-crank with only a slider mass", "[forces]") {
  const auto model = compile(R"y(
name: sc
parameters: {l: 2.0}
bodies:
  - {name: crank, q0: [0, 0, 0]}
  - {name: rod, q0: [3, 0, 1.57]}
joints:
  - {type: revolute, i: ground, j: crank}
  - {type: revolute, i: rod, j: crank, si: [0, l], sj: [1, 0]}
  - {type: absolute_y, body: rod, value: 0}
drivers:
  - {type: absolute_angle, body: crank, f: "1.3*t + 0.4*t^2"}
)y");
  kc::ForceSpec spec;
  spec.bodies.resize(2);
  spec.bodies[1].mass = num("2.5");  // the slider block sits at the rod's origin
  spec.gravity = vec("0", "-9.81");  // does no work: the slider stays at y = 0
  const auto forces = kc::derive_forces(*model, spec);
  const auto names = kc::force_columns(model->mechanism());
  REQUIRE(names == std::vector<std::string>{"driver0.effort", "joint0.fx", "joint0.fy",
                                            "joint0.tz", "joint1.fx", "joint1.fy", "joint1.tz",
                                            "joint2.fx", "joint2.fy", "joint2.tz"});
  double worst = 0;
  for (const auto& r : solve(*model, forces, 3.0, 90)) {
    const double torque = r.columns[0];
    const double power = torque * r.qd[2];
    const double kinetic_rate = 2.5 * r.qdd[3] * r.qd[3];  // d/dt (m xd^2 / 2)
    worst = std::max(worst, std::abs(power - kinetic_rate) / (1 + std::abs(kinetic_rate)));
    // The slider's guide (absolute_y at the rod's origin) pushes along y only, with no
    // torque about its point; the rod is then a two-force member: the pin's force on the
    // crank lies along the rod.
    CHECK(std::abs(r.columns[7]) < 1e-9);
    CHECK(std::abs(r.columns[9]) < 1e-9);
    const Eigen::Vector2d along(std::cos(r.q[5] + M_PI / 2), std::sin(r.q[5] + M_PI / 2));
    CHECK(std::abs(cross(along, {r.columns[4], r.columns[5]})) < 1e-9);
  }
  CHECK(worst < 1e-12);
}

TEST_CASE("forces: an accelerating crank under gravity, in closed form", "[forces]") {
  const auto model = compile(R"y(
name: crank
bodies:
  - {name: crank, q0: [0, 0, 0.3]}
joints:
  - {type: revolute, i: ground, j: crank}
drivers:
  - {type: absolute_angle, body: crank, f: "0.3 + 0.7*t + 1.1*t^2/2"}
)y");
  const double m = 1.7, jc = 0.05, rc = 0.4, g = 9.81, alpha = 1.1;
  kc::ForceSpec spec;
  spec.bodies.resize(1);
  spec.bodies[0].mass = num("1.7");
  spec.bodies[0].inertia = num("0.05");
  spec.bodies[0].com = vec("0.4", "0");
  spec.gravity = vec("0", "-9.81");
  const auto forces = kc::derive_forces(*model, spec);
  for (const auto& r : solve(*model, forces, 4.0, 40)) {
    const double phi = r.q[2], omega = r.qd[2];
    CAPTURE(r.t);
    CHECK(r.columns[0] ==
          Approx((jc + m * rc * rc) * alpha + m * g * rc * std::cos(phi)).epsilon(1e-13));
    // The pin's force on the crank: m a_com - m g.
    const Eigen::Vector2d c = rot(phi, {rc, 0});
    const Eigen::Vector2d a_com = alpha * Eigen::Vector2d(-c[1], c[0]) - omega * omega * c;
    CHECK(r.columns[1] == Approx(m * a_com[0]).margin(1e-12));
    CHECK(r.columns[2] == Approx(m * a_com[1] + m * g).margin(1e-12));
    CHECK(std::abs(r.columns[3]) < 1e-12);  // a revolute carries no torque
  }
}

namespace {
const char* kFourBar = R"y(
name: fb
parameters: {a: 1.0, b: 3.5, c: 2.5, d: 3.0}
bodies:
  - {name: crank, q0: [0, 0, 0]}
  - {name: coupler, q0: [1, 0, 0.78]}
  - {name: rocker, q0: [3, 0, 1.37]}
joints:
  - {type: revolute, i: ground, j: crank}
  - {type: revolute, i: crank, j: coupler, si: [a, 0]}
  - {type: revolute, i: coupler, j: rocker, si: [b, 0], sj: [c, 0]}
  - {type: revolute, i: ground, j: rocker, si: [d, 0]}
drivers:
  - {type: absolute_angle, body: crank, f: "1.2*t + 0.3*sin(t)"}
)y";

kc::ForceSpec four_bar_masses() {
  kc::ForceSpec spec;
  spec.bodies.resize(3);
  const char* mass[] = {"0.8", "2.1", "1.4"};
  const char* inertia[] = {"0.03", "0.9", "0.4"};
  const char* cx[] = {"0.5", "1.6", "1.2"};
  const char* cy[] = {"0.05", "0.4", "-0.1"};
  for (int b = 0; b < 3; ++b) {
    spec.bodies[b].mass = num(mass[b]);
    spec.bodies[b].inertia = num(inertia[b]);
    spec.bodies[b].com = vec(cx[b], cy[b]);
  }
  spec.gravity = vec("0.3", "-9.81");
  return spec;
}
}  // namespace

TEST_CASE("forces: Newton's and Euler's laws hold for every body of a four-bar", "[forces]") {
  const auto model = compile(kFourBar);
  const auto spec = four_bar_masses();
  const auto forces = kc::derive_forces(*model, spec);
  const Eigen::Vector2d g(0.3, -9.81);
  // Where each joint acts on each of its bodies (local points), and which body reports it.
  struct Pin { int i, j; Eigen::Vector2d si, sj; };
  const Pin pins[] = {{-1, 0, {0, 0}, {0, 0}}, {0, 1, {1, 0}, {0, 0}},
                      {1, 2, {3.5, 0}, {2.5, 0}}, {-1, 2, {3, 0}, {0, 0}}};
  double worst = 0;
  for (const auto& r : solve(*model, forces, 6.0, 72)) {
    std::vector<Eigen::Vector2d> force(3, Eigen::Vector2d::Zero());
    std::vector<double> moment(3, 0.0);  // about each centre of mass
    std::vector<Eigen::Vector2d> com(3);
    for (int b = 0; b < 3; ++b)
      com[b] = r.q.segment<2>(3 * b) + rot(r.q[3 * b + 2], com_of(forces, b));
    moment[0] += r.columns[0];  // the driver's torque on the crank
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d f(r.columns[1 + 3 * k], r.columns[2 + 3 * k]);
      const double tz = r.columns[3 + 3 * k];
      const Pin& p = pins[k];
      const Eigen::Vector2d at = r.q.segment<2>(3 * p.j) + rot(r.q[3 * p.j + 2], p.sj);
      force[p.j] += f;
      moment[p.j] += tz + cross(at - com[p.j], f);
      if (p.i >= 0) {  // the same pin pushes body i back (Newton's third law)
        force[p.i] -= f;
        moment[p.i] -= tz + cross(at - com[p.i], f);
      }
    }
    for (int b = 0; b < 3; ++b) {
      const kc::PointState c = kc::point_state(r.q.segment<3>(3 * b), r.qd.segment<3>(3 * b),
                                               r.qdd.segment<3>(3 * b), com_of(forces, b));
      const Eigen::Vector2d residual = force[b] + forces.numbers.mass[b] * g - forces.numbers.mass[b] * c.a;
      const double euler = moment[b] - forces.numbers.inertia[b] * r.qdd[3 * b + 2];
      worst = std::max({worst, residual.norm(), std::abs(euler)});
    }
  }
  CHECK(worst < 1e-10);
}

TEST_CASE("forces: power balance with a spring-damper, a force and a torque", "[forces]") {
  const auto model = compile(kFourBar);
  auto spec = four_bar_masses();
  kc::Load spring;
  spring.kind = kc::Load::Kind::kSpringDamper;
  spring.item = "forces[0] (spring_damper)";
  spring.i = kc::kGround;
  spring.j = 2;
  spring.si = vec("4.5", "2.0");
  spring.sj = vec("1.5", "0.2");
  spring.stiffness = num("40");
  spring.damping = num("3");
  spring.length0 = num("1.2");
  spring.preload = num("5");
  kc::Load push;
  push.kind = kc::Load::Kind::kForce;
  push.item = "forces[1] (force)";
  push.body = 1;
  push.s = vec("2", "0.5");
  push.f = {num("-3*cos(t)"), num("2 + x_coupler")};
  kc::Load twist;
  twist.kind = kc::Load::Kind::kTorque;
  twist.item = "forces[2] (torque)";
  twist.body = 2;
  twist.value = num("0.7*sin(phi_rocker)");
  spec.loads = {spring, push, twist};
  const auto forces = kc::derive_forces(*model, spec);
  const Eigen::Vector2d g(0.3, -9.81);
  double worst = 0, largest = 0;
  for (const auto& r : solve(*model, forces, 6.0, 120)) {
    // dKE/dt of the bodies, from their centre-of-mass kinematics.
    double kinetic_rate = 0, applied = 0;
    for (int b = 0; b < 3; ++b) {
      const kc::PointState c = kc::point_state(r.q.segment<3>(3 * b), r.qd.segment<3>(3 * b),
                                               r.qdd.segment<3>(3 * b), com_of(forces, b));
      kinetic_rate += forces.numbers.mass[b] * c.a.dot(c.v) +
                      forces.numbers.inertia[b] * r.qdd[3 * b + 2] * r.qd[3 * b + 2];
      applied += forces.numbers.mass[b] * g.dot(c.v);
    }
    // The spring-damper: tension T against the rate of its length.
    const kc::PointState p = kc::point_state(r.q.segment<3>(6), r.qd.segment<3>(6),
                                             r.qdd.segment<3>(6), {1.5, 0.2});
    const Eigen::Vector2d d = p.r - Eigen::Vector2d(4.5, 2.0);
    const double length = d.norm(), rate = d.dot(p.v) / length;
    applied -= (40 * (length - 1.2) + 3 * rate + 5) * rate;
    // The force on the coupler at [2, 0.5], the torque on the rocker.
    const kc::PointState f = kc::point_state(r.q.segment<3>(3), r.qd.segment<3>(3),
                                             r.qdd.segment<3>(3), {2, 0.5});
    applied += Eigen::Vector2d(-3 * std::cos(r.t), 2 + r.q[3]).dot(f.v);
    applied += 0.7 * std::sin(r.q[8]) * r.qd[8];
    const double driver_power = r.columns[0] * r.qd[2];
    worst = std::max(worst, std::abs(driver_power + applied - kinetic_rate));
    largest = std::max(largest, std::abs(kinetic_rate) + std::abs(applied));
  }
  CHECK(worst < 1e-10 * largest);
}

TEST_CASE("forces: bad mass data is refused", "[forces]") {
  const auto model = compile(kFourBar);
  auto spec = four_bar_masses();
  spec.bodies[1].mass = num("-1");
  CHECK_THROWS_WITH(kc::derive_forces(*model, spec), Catch::Contains("must not be negative"));
  spec = four_bar_masses();
  spec.bodies[2].inertia = num("1/0");
  CHECK_THROWS_AS(kc::derive_forces(*model, spec), kc::InputError);
}

namespace {
std::string load_error(const std::string& yaml) {
  try {
    const auto model = compile(yaml);
    kc::derive_forces(*model);
  } catch (const kc::InputError& e) {
    return e.item() + " line " + std::to_string(e.loc().line) + ": " + e.detail();
  }
  return "no error";
}
const std::string kBase = R"y(name: m
bodies:
  - {name: crank, q0: [0, 0, 0], mass: 2, inertia: 0.1, com: [0.5, 0]}
joints:
  - {type: revolute, i: ground, j: crank}
drivers:
  - {type: absolute_angle, body: crank, f: "t"}
)y";
}  // namespace

TEST_CASE("forces from the file: keys, defaults and hostile values", "[forces]") {
  // Read from YAML, a spring between ground and the crank tip: the torque it needs at rest.
  const auto model = compile(kBase + R"y(gravity: [0, -10]
forces:
  - {type: rotational_spring_damper, name: coil, i: ground, j: crank, stiffness: 3}
  - {type: torque, body: crank, value: "0.5"}
)y");
  const auto forces = kc::derive_forces(*model);
  kc::ForceSolver solver(*model, forces);
  std::vector<double> columns;
  Eigen::VectorXd q(3), qd = Eigen::VectorXd::Zero(3), qdd = Eigen::VectorXd::Zero(3);
  q << 0, 0, 0.25;
  REQUIRE(solver.solve(0.25, q, qd, qdd, columns));
  // Static balance: motor + 0.5 - 3 phi - m g rc cos(phi) = 0.
  CHECK(columns[0] == Approx(3 * 0.25 + 2 * 10 * 0.5 * std::cos(0.25) - 0.5).epsilon(1e-14));

  CHECK_THAT(load_error(R"y(name: m
bodies:
  - {name: crank, q0: [0, 0, 0], mass: -2}
joints:
  - {type: revolute, i: ground, j: crank}
drivers:
  - {type: absolute_angle, body: crank, f: "t"}
)y"),
             Catch::Contains("body 'crank' mass line 3") && Catch::Contains("must not be negative"));
  CHECK_THAT(load_error(kBase + "forces:\n  - {type: force, body: rod, f: [1, 0]}\n"),
             Catch::Contains("forces[0] (force) line 9") && Catch::Contains("unknown body 'rod'"));
  // A force's f and a torque's value may use velocities; a spring's constants may not.
  CHECK(load_error(kBase + "forces:\n  - {type: force, body: crank, f: [\"-0.5*xd_crank\", 0]}\n") ==
        "no error");
  CHECK(load_error(kBase + "forces:\n  - {type: torque, body: crank, value: \"-phid_crank\"}\n") ==
        "no error");
  CHECK_THAT(load_error(kBase +
                        "forces:\n  - {type: spring_damper, i: ground, j: crank, stiffness: "
                        "\"phid_crank\", length0: 1}\n"),
             Catch::Contains("forces[0] (spring_damper) stiffness line 9") &&
                 Catch::Contains("uses the velocity 'phi_crank_dot'") &&
                 Catch::Contains("damping gives its own"));
  CHECK_THAT(load_error(kBase + "forces:\n  - {type: spring_damper, i: ground, j: crank, "
                                "stiffness: \"1/0\", length0: 1}\n"),
             Catch::Contains("forces[0] (spring_damper)") && Catch::Contains("stiffness line 9"));
  CHECK_THAT(load_error(kBase + "forces:\n  - {type: spring_damper, i: ground, j: crank, "
                                "stiffness: .inf, length0: 1}\n"),
             Catch::Contains("not a finite number"));
  CHECK_THAT(load_error(kBase + "forces:\n  - {type: spring, i: ground, j: crank}\n"),
             Catch::Contains("unknown load type 'spring'"));
  CHECK_THAT(load_error(kBase + "forces:\n  - {type: torque, body: crank, value: 1, s: [0, 0]}\n"),
             Catch::Contains("unknown key 's'"));
  CHECK(load_error(kBase) == "no error");
}

TEST_CASE("forces: the double path agrees with the 40-digit reference", "[forces]") {
  const auto model = compile(kFourBar);
  auto spec = four_bar_masses();
  kc::Load spring;
  spring.kind = kc::Load::Kind::kSpringDamper;
  spring.item = "forces[0] (spring_damper)";
  spring.j = 1;
  spring.si = vec("1/3", "2.0");
  spring.sj = vec("1.5", "0.2");
  spring.stiffness = num("40");
  spring.damping = num("3");
  spring.length0 = num("1.2");
  spring.preload = num("0");
  spec.loads = {spring};
  const auto forces = kc::derive_forces(*model, spec);
  const auto rows = solve(*model, forces, 6.0, 24);
  kc::ReferenceForces reference(*model, forces, 40);
  std::size_t k = 0;
  double worst = 0;
  kc::run_reference_analysis_exact(*model, {0, 6.0, 24}, 40, [&](const kc::ReferenceRow& r) {
    const auto exact = reference.solve(r);
    REQUIRE(exact.size() == rows[k].columns.size());
    double scale = 0;
    for (const auto& v : exact) scale = std::max(scale, std::abs(v.to_double()));
    for (std::size_t c = 0; c < exact.size(); ++c)
      worst = std::max(worst, std::abs(rows[k].columns[c] - exact[c].to_double()) / scale);
    ++k;
  });
  CHECK(k == rows.size());
  CHECK(worst < 1e-14);  // measured 9.8e-16 of the largest column
  CHECK(worst > 0);  // two independent roundings, not one path twice
}

TEST_CASE("analyze --forces from the command line", "[forces][cli]") {
  namespace fs = std::filesystem;
  const std::string exe = KINEGEN_EXE;
  const std::string example = std::string(KINEGEN_SOURCE_DIR) + "/examples/forces/four_bar_balanced.yaml";
  auto r = kinegen::test::run_command(
      {exe, "analyze", example, "--t0", "0", "--t1", "1", "--steps", "8", "--forces"});
  REQUIRE(r.exit_code == 0);
  const std::string header = r.out.substr(0, r.out.find('\n'));
  CHECK_THAT(header, Catch::EndsWith("P.ay,motor.effort,O2.fx,O2.fy,O2.tz,A.fx,A.fy,A.tz,B.fx,"
                                     "B.fy,B.tz,O4.fx,O4.fy,O4.tz"));
  // The reference path gives the same columns, to about double rounding.
  auto ref = kinegen::test::run_command({exe, "analyze", example, "--t0", "0", "--t1", "1",
                                         "--steps", "8", "--forces", "--reference-digits", "40"});
  REQUIRE(ref.exit_code == 0);
  CHECK(ref.out.substr(0, ref.out.find('\n')) == header);
  // Hostile input: one error line with the item and its line, exit 2, no output file.
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "forces_cli";
  fs::create_directories(dir);
  const std::string bad = (dir / "bad.yaml").string();
  std::ofstream(bad) << kBase << "forces:\n  - {type: force, body: crank, f: [1, 0], s: [\"1/0\", 0]}\n";
  const std::string csv = (dir / "out.csv").string();
  fs::remove(csv);
  r = kinegen::test::run_command({exe, "analyze", bad, "--t0", "0", "--t1", "1", "--steps", "2",
                                  "--forces", "-o", csv});
  CHECK(r.exit_code == 2);
  CHECK_THAT(r.err, Catch::StartsWith("error: ") && Catch::Contains(":9:"));
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK_FALSE(fs::exists(csv));
  // Without masses or loads: zeros, not an error.
  std::ofstream(dir / "plain.yaml") << kBase;
  r = kinegen::test::run_command({exe, "analyze", (dir / "plain.yaml").string(), "--t0", "0",
                                  "--t1", "1", "--steps", "2", "--forces"});
  CHECK(r.exit_code == 0);
}

TEST_CASE("bad masses and loads are input errors for every command, not only with --forces",
          "[forces][cli]") {
  namespace fs = std::filesystem;
  const std::string exe = KINEGEN_EXE;
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "forces_every_command";
  fs::remove_all(dir);
  fs::create_directories(dir);
  // Each file is kBase and one bad line after it; the message names the item.
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"forces:\n  - {type: force, body: crank, f: [\"nosuch\", 0]}\n", "unknown symbol 'nosuch'"},
      {"forces:\n  - {type: torque, body: crank, value: \"xd_nosuch\"}\n", "forces[0] (torque)"},
      {"forces:\n  - {type: spring_damper, i: ground, j: crank, stiffness: \"1/0\", "
       "length0: 1}\n",
       "stiffness"},
      {"gravity: [0, \"g\"]\n", "gravity"},
  };
  const std::string out = (dir / "out").string();
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const std::string file = (dir / ("bad" + std::to_string(k) + ".yaml")).string();
    std::ofstream(file) << kBase << cases[k].first;
    const std::vector<std::vector<std::string>> commands = {
        {exe, "analyze", file, "--t0", "0", "--t1", "1", "--steps", "2", "-o", out},
        {exe, "generate", file, "-o", out},
        {exe, "generate", file, "-o", out, "--outputs", "position"},
        {exe, "check", file},
        {exe, "eval", file},
        {exe, "animate", file, "--t0", "0", "--t1", "1", "--steps", "2", "-o", out},
    };
    for (const auto& command : commands) {
      std::string line;
      for (std::size_t a = 1; a < command.size(); ++a) line += command[a] + " ";
      INFO(cases[k].first << line);
      const auto r = kinegen::test::run_command(command);
      CHECK(r.exit_code == 2);
      CHECK_THAT(r.err,
                 Catch::StartsWith("error: " + file + ":") && Catch::Contains(cases[k].second));
      CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
      CHECK_FALSE(fs::exists(out));
    }
  }
  // The line is the load's own (kBase has 7 lines, then `forces:`).
  const auto r = kinegen::test::run_command({exe, "check", (dir / "bad0.yaml").string()});
  CHECK_THAT(r.err, Catch::Contains(".yaml:9:"));
}

TEST_CASE("forces near a toggle: a warning as the condition grows, then the singular error",
          "[forces][cli]") {
  const std::string exe = KINEGEN_EXE;
  const std::string mech =
      std::string(KINEGEN_SOURCE_DIR) + "/tests/stability/slider_toggle_forces.yaml";
  const std::string csv = std::string(KINEGEN_TEST_TMP) + "/slider_toggle_forces.csv";
  const auto r = kinegen::test::run_command({exe, "analyze", mech, "--t0", "0", "--t1", "1",
                                             "--steps", "2000", "--forces", "-o", csv});
  CHECK(r.exit_code == 1);  // the dead centre at t = 1 is singular
  CHECK_THAT(r.err, Catch::Contains("warning:") && Catch::Contains("nears a toggle") &&
                        Catch::Contains("error:") && Catch::Contains("failed at t = 1 (") &&
                        Catch::Contains("singular"));
  // The rows before are kept, and the piston force grows without bound towards the toggle:
  // with a constant torque on the crank, |F| ~ 1 / (r sin(crank angle)).
  std::ifstream in(csv);
  std::string line, header;
  std::getline(in, header);
  int column = 0;
  for (std::size_t p = 0, q; (q = header.find(',', p)) != std::string::npos || p < header.size();
       p = q + 1, ++column) {
    if (header.substr(p, (q == std::string::npos ? header.size() : q) - p) == "piston.effort")
      break;
    if (q == std::string::npos) break;
  }
  std::vector<double> effort;
  while (std::getline(in, line)) {
    std::stringstream s(line);
    std::string cell;
    for (int c = 0; c <= column; ++c) std::getline(s, cell, ',');
    effort.push_back(std::stod(cell));
  }
  REQUIRE(effort.size() == 2000);  // t = 0 .. 1 - 1/2000: every row before the toggle
  CHECK(std::abs(effort.back()) > 100 * std::abs(effort.front()));
}

TEST_CASE("forces on a redundant model: refused, naming the redundant equations", "[forces][cli]") {
  namespace fs = std::filesystem;
  // A parallelogram with a third crank parallel to the other two: 13 equations for 12
  // coordinates, consistent, so the analysis runs (with a warning) but the reactions of the
  // cranks are not unique. The last joint closes the redundant loop.
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "forces_redundant";
  fs::create_directories(dir);
  const std::string mech = (dir / "parallelogram.yaml").string();
  std::ofstream(mech) << R"y(name: parallelogram
bodies:
  - {name: crank, q0: [0, 0, 1], mass: 1}
  - {name: coupler, q0: [0.54, 0.84, 0], mass: 2}
  - {name: rocker, q0: [2, 0, 1], mass: 1}
  - {name: extra, q0: [1, 0, 1], mass: 1}
gravity: [0, -9.81]
joints:
  - {type: revolute, name: O2, i: ground, j: crank}
  - {type: revolute, name: A, i: crank, j: coupler, si: [1, 0]}
  - {type: revolute, name: B, i: coupler, j: rocker, si: [2, 0], sj: [1, 0]}
  - {type: revolute, name: O4, i: ground, j: rocker, si: [2, 0]}
  - {type: revolute, name: E1, i: ground, j: extra, si: [1, 0]}
  - {type: revolute, name: E2, i: coupler, j: extra, si: [1, 0], sj: [1, 0]}
drivers:
  - {type: absolute_angle, name: motor, body: crank, f: "1 + t"}
)y";
  const std::string exe = KINEGEN_EXE, csv = (dir / "out.csv").string();
  fs::remove(csv);
  // The kinematics alone run, with the redundancy warning.
  auto r = kinegen::test::run_command({exe, "analyze", mech, "--t0", "0", "--t1", "1", "--steps",
                                       "4", "-o", csv});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  fs::remove(csv);
  r = kinegen::test::run_command({exe, "analyze", mech, "--t0", "0", "--t1", "1", "--steps", "4",
                                  "--forces", "-o", csv});
  CHECK(r.exit_code == 2);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK_THAT(r.err, Catch::StartsWith("error: ") && Catch::Contains("not unique") &&
                        Catch::Contains("remove the redundant equations") &&
                        Catch::Contains("E2"));
  CHECK_FALSE(fs::exists(csv));
}

TEST_CASE("forces: the press example's motor work over a cycle is the forming work",
          "[forces][laws]") {
  // examples/forces/press.yaml: no gravity, so over one cycle (the kinetic energy back where
  // it started) the motor's work, the integral of effort * omega, equals the work done against
  // the forming force, the integral of -f_x * v_ram, each from its own columns: the torque
  // from Phi_q^T lambda = Q, the force work from the kinematics and the load's formula
  // (written out here with the 3-4-5 law).
  const auto model = kc::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                  "/examples/forces/press.yaml");
  const auto forces = kc::forces_for_analysis(*model);
  const double r = 0.05, l = 0.2, f = 5000, contact = 0.02, ramp = 0.002, window = 0.05,
               pi = std::acos(-1.0);
  const auto poly345 = [](double x) {
    x = std::clamp(x, 0.0, 1.0);
    return x * x * x * (10 - 15 * x + 6 * x * x);
  };
  const int steps = 7200;
  std::vector<double> motor, forming;
  double worst_power = 0, largest_power = 0;
  kc::ForceSolver solver(*model, forces);
  kc::run_analysis(*model, {0, 1, steps}, [&](const kc::StateRow& row) {
    std::vector<double> columns;
    REQUIRE(solver.solve(row.t, row.q, row.qd, row.qdd, columns));
    motor.push_back(columns[0] * row.qd[2]);  // motor.effort * crank rate
    const double x = row.q[6], phi = row.q[2];
    const double fx = -f * poly345((x - (r + l - contact)) / ramp) *
                      (1 - poly345((phi - 2 * pi) / window));
    forming.push_back(-fx * row.qd[6]);
    // Row by row: motor power plus the force's equals dKE/dt, from the file's masses (crank
    // J 0.02; rod m 1.2, J 0.004, com [0.1, 0]; ram m 6) and the rows' kinematics.
    const kc::PointState rod = kc::point_state(row.q.segment<3>(3), row.qd.segment<3>(3),
                                               row.qdd.segment<3>(3), {0.1, 0});
    const double kinetic_rate = 0.02 * row.qd[2] * row.qdd[2] + 1.2 * rod.a.dot(rod.v) +
                                0.004 * row.qd[5] * row.qdd[5] + 6 * row.qdd[6] * row.qd[6];
    const double power = motor.back() + fx * row.qd[6];
    worst_power = std::max(worst_power, std::abs(power - kinetic_rate));
    largest_power = std::max(largest_power, std::abs(motor.back()) + std::abs(kinetic_rate));
  });
  INFO("power balance: worst " << worst_power << " W of " << largest_power << " W");
  CHECK(worst_power <= 1e-10 * largest_power);
  REQUIRE(motor.size() == steps + 1u);
  // Simpson's rule over the cycle.
  const auto integral = [&](const std::vector<double>& v) {
    double s = v.front() + v.back();
    for (int k = 1; k < steps; ++k) s += (k % 2 ? 4 : 2) * v[k];
    return s / (3.0 * steps);
  };
  const double w_motor = integral(motor), w_forming = integral(forming);
  INFO("motor work " << w_motor << " J, forming work " << w_forming << " J");
  // About F (contact - ramp / 2) = 95 J, less what the tool gives back as the window closes.
  CHECK(w_forming == Approx(95).epsilon(0.01));
  CHECK(w_motor == Approx(w_forming).epsilon(1e-6));
}

TEST_CASE("forces: power balance on the table-driven press over three cycles", "[forces][pieces]") {
  // examples/forces/table_press.yaml over three cycles of its periodic motor table: on every
  // row the motor's power plus the forming force's equals dKE/dt (masses as in press.yaml),
  // and each cycle's motor work is its forming work.
  const auto model = kc::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                  "/examples/forces/table_press.yaml");
  const auto forces = kc::forces_for_analysis(*model);
  const double r = 0.05, l = 0.2, f = 5000, contact = 0.02, ramp = 0.002, window = 0.05;
  const auto poly345 = [](double x) {
    x = std::clamp(x, 0.0, 1.0);
    return x * x * x * (10 - 15 * x + 6 * x * x);
  };
  kc::ForceSolver solver(*model, forces);
  double worst = 0, largest = 0;
  std::vector<double> work(3, 0.0), forming(3, 0.0);
  const int per_cycle = 2400;
  double h = 1.0 / per_cycle;
  kc::run_analysis(*model, {0, 3, 3 * per_cycle}, [&](const kc::StateRow& row) {
    std::vector<double> columns;
    REQUIRE(solver.solve(row.t, row.q, row.qd, row.qdd, columns));
    const double fx = -f * poly345((row.q[6] - (r + l - contact)) / ramp) *
                      (1 - poly345(std::sin(row.q[2]) / window));
    const double motor = columns[0] * row.qd[2];
    const kc::PointState rod = kc::point_state(row.q.segment<3>(3), row.qd.segment<3>(3),
                                               row.qdd.segment<3>(3), {0.1, 0});
    const double kinetic_rate = 0.02 * row.qd[2] * row.qdd[2] + 1.2 * rod.a.dot(rod.v) +
                                0.004 * row.qd[5] * row.qdd[5] + 6 * row.qdd[6] * row.qd[6];
    worst = std::max(worst, std::abs(motor + fx * row.qd[6] - kinetic_rate));
    largest = std::max(largest, std::abs(motor) + std::abs(kinetic_rate));
    // Trapezoidal sums per cycle (the ends count half).
    const int k = static_cast<int>(std::lround(row.t / h));
    const int cycle = std::min(2, k / per_cycle);
    const double weight = (k % per_cycle == 0) ? 0.5 : 1.0;
    work[cycle] += weight * motor * h;
    forming[cycle] += weight * -fx * row.qd[6] * h;
    if (k % per_cycle == 0 && k > 0 && k / per_cycle - 1 < 3 && k / per_cycle - 1 != cycle) {
      work[k / per_cycle - 1] += 0.5 * motor * h;
      forming[k / per_cycle - 1] += 0.5 * -fx * row.qd[6] * h;
    }
  });
  INFO("power balance: worst " << worst << " W of " << largest << " W");
  CHECK(worst <= 1e-10 * largest);
  for (int c = 0; c < 3; ++c) {
    INFO("cycle " << c << ": motor work " << work[c] << " J, forming work " << forming[c] << " J");
    CHECK(forming[c] == Approx(95).epsilon(0.02));  // every cycle forms
    CHECK(work[c] == Approx(forming[c]).epsilon(1e-3));
  }
}

TEST_CASE("forces: power balance over a turn of the balanced four-bar example", "[forces]") {
  // examples/forces/four_bar_balanced.yaml, every row of a turn: the motor's power (effort
  // times crank rate) plus gravity's and the spring-damper's equals the rate of the kinetic
  // energy, each written out here from the file's data and the rows' kinematics.
  const auto model = kc::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                  "/examples/forces/four_bar_balanced.yaml");
  const auto forces = kc::forces_for_analysis(*model);
  const double a = 0.1, b = 0.35, c = 0.25, k = 400, damping = 0.5, length0 = 0.15, g = 9.81;
  const double mass[3] = {0.4, 1.2, 0.9}, inertia[3] = {0.0004, 0.012, 0.005};
  const Eigen::Vector2d com[3] = {{a / 2, 0}, {b / 2, 0.02}, {c / 2, 0}};
  const Eigen::Vector2d anchor(0.3, 0.4), on_rocker(c / 2, 0);
  kc::ForceSolver solver(*model, forces);
  double largest = 0, worst = 0;
  kc::run_analysis(*model, {0, 1, 360}, [&](const kc::StateRow& row) {
    std::vector<double> columns;
    REQUIRE(solver.solve(row.t, row.q, row.qd, row.qdd, columns));
    double kinetic_rate = 0, gravity = 0;
    for (int body = 0; body < 3; ++body) {
      const double phi = row.q[3 * body + 2], w = row.qd[3 * body + 2],
                   al = row.qdd[3 * body + 2];
      const Eigen::Vector2d s = rot(phi, com[body]), perp(-s[1], s[0]);
      const Eigen::Vector2d v = row.qd.segment<2>(3 * body) + w * perp;
      const Eigen::Vector2d acc = row.qdd.segment<2>(3 * body) + al * perp - w * w * s;
      kinetic_rate += mass[body] * v.dot(acc) + inertia[body] * w * al;
      gravity += -mass[body] * g * v[1];
    }
    // The spring from the ground anchor to the rocker's middle: tension k (L - L0) + c dL/dt
    // pulls the ends together, so its power is -tension dL/dt.
    const double phi = row.q[8], w = row.qd[8];
    const Eigen::Vector2d s = rot(phi, on_rocker), perp(-s[1], s[0]);
    const Eigen::Vector2d d = row.q.segment<2>(6) + s - anchor;
    const Eigen::Vector2d v = row.qd.segment<2>(6) + w * perp;
    const double length = d.norm(), length_rate = d.dot(v) / length;
    const double spring = -(k * (length - length0) + damping * length_rate) * length_rate;
    const double motor = columns[0] * row.qd[2];
    largest = std::max({largest, std::abs(kinetic_rate), std::abs(gravity), std::abs(spring),
                        std::abs(motor)});
    worst = std::max(worst, std::abs(motor + gravity + spring - kinetic_rate));
  });
  INFO("largest power " << largest << " W, worst imbalance " << worst << " W");
  CHECK(worst <= 1e-10 * largest);
}
