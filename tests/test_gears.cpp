// Joint types fixed, gear and rack_pinion against closed forms:
// - an external pair on fixed centres over many turns: phi_j = -(ri/rj) phi_i;
// - a planetary carrier turning many revolutions (sun fixed): Willis' equation, with the line
//   of centres through +-pi every turn;
// - an internal pair (ring and carrier both driven): Willis' equation for an internal mesh;
//   the planetary example (ring fixed, sun driven) likewise;
// - a driven rack (x = rj phi) and a pinion rolling on a fixed, tilted rack (s = -rj phi);
// - a weld: the welded body moves as part of the other;
// - the 40-digit reference against the double analysis, the generated headers against
//   analyze, the mesh torque of `--forces` against J alpha;
// - hostile input (one error line, exit 2, no output) and the centre-distance warning.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "gear_pair.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "planetary.hpp"
#include "support/files.hpp"
#include "support/run_command.hpp"

namespace {

namespace kc = kinegen::codegen;
namespace km = kinegen::models;
namespace fs = std::filesystem;

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kPi = 3.14159265358979323846;

struct Run {
  std::vector<kc::StateRow> rows;
  std::vector<std::string> warnings;
};

Run analyze(const kc::CompiledModel& model, const kc::TimeGrid& grid) {
  Run run;
  kc::AnalysisOptions options;
  options.warn = [&](const std::string& w) { run.warnings.push_back(w); };
  kc::run_analysis(
      model, grid, [&](const kc::StateRow& r) { run.rows.push_back(r); }, options);
  return run;
}

Run analyze(const std::string& yaml, const kc::TimeGrid& grid) {
  const auto model = kc::CompiledModel::from_mechanism(kc::parse_mechanism(yaml, "gears.yaml"));
  return analyze(*model, grid);
}

// The largest |a - b| / (1 + |b|) seen, per block.
struct Error {
  double q = 0, qd = 0, qdd = 0;
  void add(double& block, double value, double truth) {
    block = std::max(block, std::abs(value - truth) / (1 + std::abs(truth)));
  }
};

std::string source_dir() { return KINEGEN_SOURCE_DIR; }

}  // namespace

TEST_CASE("gears: an external pair on fixed centres over many turns", "[gears]") {
  // gear_pair.yaml: ri 0.03, rj 0.075, phi_pinion = 3 t + t^2 (130 rad, 20 turns, at t = 10).
  const auto model =
      kc::CompiledModel::from_file(source_dir() + "/tests/mechanisms/gear_pair.yaml");
  const Run run = analyze(*model, {0, 10, 2000});
  CHECK(run.warnings.empty());
  const double ratio = -0.03 / 0.075;
  Error e;
  for (const auto& r : run.rows) {
    const double t = r.t, phi = 3 * t + t * t, omega = 3 + 2 * t, alpha = 2;
    e.add(e.q, r.q[2], phi);
    e.add(e.q, r.q[3], 0.105);
    e.add(e.q, r.q[4], 0);
    e.add(e.q, r.q[5], ratio * phi);
    e.add(e.qd, r.qd[5], ratio * omega);
    e.add(e.qdd, r.qdd[5], ratio * alpha);
  }
  INFO("largest relative error: q " << e.q << ", qd " << e.qd << ", qdd " << e.qdd);
  CHECK(run.rows.back().q[5] == Approx(ratio * 130).epsilon(1e-14));
  CHECK(e.q <= 16 * kEps);
  CHECK(e.qd <= 16 * kEps);
  CHECK(e.qdd <= 16 * kEps);
}

TEST_CASE("gears: a planetary carrier over 39 turns follows Willis' equation", "[gears]") {
  // Sun fixed (ground, r_s 0.05), planet r_p 0.02 on a carrier arm a = 0.07 driven at
  // theta = 2 pi t + 0.3 t^2: the line of centres passes +-pi every turn.
  const std::string yaml = R"Y(name: carrier
bodies:
  - {name: carrier, q0: [0, 0, 0]}
  - {name: planet, q0: [0.07, 0, 0]}
joints:
  - {type: revolute, i: ground, j: carrier}
  - {type: revolute, i: carrier, j: planet, si: [0.07, 0]}
  - {type: gear, name: mesh, i: ground, j: planet, ri: 0.05, rj: 0.02}
drivers:
  - {type: absolute_angle, body: carrier, f: "2*pi*t + 0.3*t^2"}
)Y";
  const Run run = analyze(yaml, {0, 20, 2000});
  CHECK(run.warnings.empty());
  const double rs = 0.05, rp = 0.02, a = 0.07;
  Error e;
  double willis = 0;
  for (const auto& r : run.rows) {
    const double t = r.t, th = 2 * kPi * t + 0.3 * t * t, w = 2 * kPi + 0.6 * t, al = 0.6;
    const double w_planet = r.qd[5];
    // (omega_planet - omega_carrier) / (omega_sun - omega_carrier) = -r_s / r_p, omega_sun = 0.
    willis = std::max(willis, std::abs((w_planet - w) / (0 - w) + rs / rp));
    e.add(e.q, r.q[3], a * std::cos(th));
    e.add(e.q, r.q[4], a * std::sin(th));
    e.add(e.q, r.q[5], (1 + rs / rp) * th);
    e.add(e.qd, r.qd[3], -a * std::sin(th) * w);
    e.add(e.qd, r.qd[5], (1 + rs / rp) * w);
    e.add(e.qdd, r.qdd[4], a * (std::cos(th) * al - std::sin(th) * w * w));
    e.add(e.qdd, r.qdd[5], (1 + rs / rp) * al);
  }
  const double turns = run.rows.back().q[2] / (2 * kPi);
  INFO("carrier turns " << turns << "; Willis residual " << willis << "; relative errors q " << e.q
                        << ", qd " << e.qd << ", qdd " << e.qdd);
  CHECK(turns > 39);
  CHECK(willis <= 64 * kEps);
  CHECK(e.q <= 64 * kEps);
  // The planet's angle reaches 860 rad, resolved to eps * 860 ~ 2e-13: sin and cos of it, and
  // so the velocities and accelerations, carry that much rounding (the closed form's too).
  const double resolution = kEps * std::abs(run.rows.back().q[5]);
  CHECK(e.qd <= 8 * resolution);
  CHECK(e.qdd <= 8 * resolution);
}

TEST_CASE("gears: an internal pair with ring and carrier driven follows Willis' equation",
          "[gears]") {
  // Ring r_r 0.1 turning at 0.7 rad/s, carrier at 2 t + 0.25 t^2, planet r_p 0.03 at a = 0.07
  // from the centre: (omega_p - omega_c) / (omega_r - omega_c) = r_r / r_p (internal mesh).
  const std::string yaml = R"Y(name: ring
bodies:
  - {name: ring, q0: [0, 0, 0]}
  - {name: carrier, q0: [0, 0, 0]}
  - {name: planet, q0: [0.07, 0, 0]}
joints:
  - {type: revolute, i: ground, j: ring}
  - {type: revolute, i: ground, j: carrier}
  - {type: revolute, i: carrier, j: planet, si: [0.07, 0]}
  - {type: gear, name: mesh, i: planet, j: ring, ri: 0.03, rj: 0.1, internal: true,
     c: "0.07*pi"}
drivers:
  - {type: absolute_angle, body: ring, f: "0.7*t"}
  - {type: absolute_angle, body: carrier, f: "2*t + 0.25*t^2"}
)Y";
  const Run run = analyze(yaml, {0, 15, 1500});
  CHECK(run.warnings.empty());
  const double rr = 0.1, rp = 0.03;
  Error e;
  double willis = 0;
  for (const auto& r : run.rows) {
    const double t = r.t, th = 2 * t + 0.25 * t * t, w = 2 + 0.5 * t, al = 0.5;
    const double pr = 0.7 * t, wr = 0.7;
    willis = std::max(willis, std::abs((r.qd[8] - w) / (wr - w) - rr / rp));
    e.add(e.q, r.q[8], th + rr / rp * (pr - th));
    e.add(e.qd, r.qd[8], w + rr / rp * (wr - w));
    e.add(e.qdd, r.qdd[8], al + rr / rp * (0 - al));
  }
  INFO("carrier turns " << run.rows.back().q[5] / (2 * kPi) << "; Willis residual " << willis
                        << "; relative errors q " << e.q << ", qd " << e.qd << ", qdd " << e.qdd);
  CHECK(willis <= 64 * kEps * rr / rp);
  CHECK(e.q <= 64 * kEps);
  // As above: the planet's angle (-166 rad at the end) resolved to eps * |phi|.
  const double resolution = kEps * std::abs(run.rows.back().q[8]);
  CHECK(e.qd <= 8 * resolution);
  CHECK(e.qdd <= 8 * resolution);
}

TEST_CASE("gears: the planetary example (ring fixed, sun driven) against Willis' equation",
          "[gears]") {
  const auto model = kc::CompiledModel::from_file(source_dir() + "/examples/gears/planetary.yaml");
  const Run run = analyze(*model, {0, 8, 960});  // 8 sun turns, 2 carrier turns
  CHECK(run.warnings.empty());
  const double rs = 0.02, rp = 0.02, rr = rs + 2 * rp, ws = 2 * kPi;
  const double wc = ws * rs / (rs + rr);  // (w_s - w_c) / (0 - w_c) = -r_r / r_s
  Error e;
  for (const auto& r : run.rows) {
    e.add(e.q, r.q[2], ws * r.t);
    e.add(e.q, r.q[5], wc * r.t);
    e.add(e.q, r.q[8], wc * r.t * (1 - rr / rp));  // (w_p - w_c) / (0 - w_c) = r_r / r_p
    e.add(e.qd, r.qd[5], wc);
    e.add(e.qd, r.qd[8], wc * (1 - rr / rp));
    e.add(e.qdd, r.qdd[8], 0);
  }
  INFO("relative errors q " << e.q << ", qd " << e.qd << ", qdd " << e.qdd);
  CHECK(e.q <= 64 * kEps);
  CHECK(e.qd <= 64 * kEps);
  CHECK(e.qdd <= 64 * kEps);
}

TEST_CASE("gears: a driven rack turns its pinion by x / rj", "[gears]") {
  // The pinion turns on a fixed axis at [0, rj]; the rack (held at angle 0, its pitch line at
  // distance rj by the mesh) is driven along x: x = rj phi.
  const std::string yaml = R"Y(name: rack
bodies:
  - {name: rack, q0: [0, 0, 0]}
  - {name: pinion, q0: [0, 0.04, 0]}
joints:
  - {type: revolute, i: ground, j: pinion, si: [0, 0.04]}
  - {type: absolute_angle, body: rack, value: 0}
  - {type: rack_pinion, i: rack, vi: [1, 0], j: pinion, rj: 0.04}
drivers:
  - {type: absolute_x, body: rack, f: "0.2*sin(t) + 0.05*t"}
)Y";
  const Run run = analyze(yaml, {0, 10, 500});
  const double rj = 0.04;
  Error e;
  for (const auto& r : run.rows) {
    const double t = r.t;
    const double x = 0.2 * std::sin(t) + 0.05 * t, xd = 0.2 * std::cos(t) + 0.05,
                 xdd = -0.2 * std::sin(t);
    e.add(e.q, r.q[1], 0);
    e.add(e.q, r.q[5], x / rj);
    e.add(e.qd, r.qd[5], xd / rj);
    e.add(e.qdd, r.qdd[5], xdd / rj);
  }
  INFO("relative errors q " << e.q << ", qd " << e.qd << ", qdd " << e.qdd);
  CHECK(e.q <= 16 * kEps);
  CHECK(e.qd <= 16 * kEps);
  CHECK(e.qdd <= 16 * kEps);
}

namespace {

// examples/gears/steering.yaml in closed form: the knuckle of side s (-1 left, +1 right) at
// the rack's travel x. Its arm's end K + A(theta) S lies the tie rod's length from the rack's
// end E: with D = K - E, |D + A S|^2 = rod^2 gives P cos(theta) + Q sin(theta) = k, solved on
// the branch through theta = 0.
double knuckle_angle(double x, int s) {
  const double rj = 0.008, a = 0.35, w = 0.62, h = 0.10, arm = 0.13, lean = 0.25;
  const double sx = s * arm * std::sin(lean), sy = arm * std::cos(lean);
  const double rod = std::hypot(w + arm * std::sin(lean) - a, sy - h);
  const double dx = s * w - (x + s * a), dy = -rj - h - (-rj);
  const double p = dx * sx + dy * sy, q = dy * sx - dx * sy;
  const double k = (rod * rod - dx * dx - dy * dy - sx * sx - sy * sy) / 2;
  const double beta = std::atan2(q, p), alpha = std::acos(k / std::hypot(p, q));
  const double t1 = beta + alpha, t2 = beta - alpha;
  return std::abs(t1) < std::abs(t2) ? t1 : t2;
}

}  // namespace

TEST_CASE("gears: rack-and-pinion steering against its closed form", "[gears]") {
  // The rack follows x = rj phi of the wheel; each knuckle the closed form above. Rates from
  // central differences of the closed form in t (steps 1e-5 and 1e-4).
  const auto model =
      kc::CompiledModel::from_file(source_dir() + "/examples/gears/steering.yaml");
  const Run run = analyze(*model, {0, 6.283185307179586, 360});
  REQUIRE(run.rows.size() == 361);
  const auto rack_x = [](double t) { return 0.008 * 4.0 * std::sin(t); };
  Error e, e_rack;
  double ackermann = 0;  // the inner wheel turns more: max over rows of |inner| - |outer|
  for (const auto& r : run.rows) {
    const double t = r.t;
    e_rack.add(e_rack.q, r.q[3], rack_x(t));
    e_rack.add(e_rack.qd, r.qd[3], 0.032 * std::cos(t));
    e_rack.add(e_rack.qdd, r.qdd[3], -0.032 * std::sin(t));
    for (const int s : {-1, 1}) {
      const int k = s < 0 ? 8 : 11;  // phi of knuckle_left, knuckle_right
      const auto theta = [&](double tt) { return knuckle_angle(rack_x(tt), s); };
      const double h1 = 1e-5, h2 = 1e-4;
      e.add(e.q, r.q[k], theta(t));
      e.add(e.qd, r.qd[k], (theta(t + h1) - theta(t - h1)) / (2 * h1));
      e.add(e.qdd, r.qdd[k], (theta(t + h2) - 2 * theta(t) + theta(t - h2)) / (h2 * h2));
    }
    const bool right_turn = r.q[3] > 0;  // the rack moves right: the car turns right
    const double inner = std::abs(r.q[right_turn ? 11 : 8]), outer = std::abs(r.q[right_turn ? 8 : 11]);
    ackermann = std::max(ackermann, inner - outer);
  }
  INFO("rack " << e_rack.q << " " << e_rack.qd << " " << e_rack.qdd << "; knuckles " << e.q << " "
               << e.qd << " " << e.qdd);
  CHECK(e_rack.q <= 16 * kEps);
  CHECK(e_rack.qd <= 16 * kEps);
  CHECK(e_rack.qdd <= 16 * kEps);
  CHECK(e.q <= 1e-14);
  CHECK(e.qd <= 1e-9);
  CHECK(e.qdd <= 1e-6);
  CHECK(ackermann > 0.01);  // the inner wheel turns more (Ackermann), by over half a degree
}

TEST_CASE("gears: a pinion rolling on a fixed tilted rack advances -rj phi", "[gears]") {
  // Pitch line through [0.1, 0.2] along vi = [3, 4] (u = [0.6, 0.8], not given as a unit
  // vector); the centre sits rj to its left and advances s = -rj phi along u.
  const std::string yaml = R"Y(name: rolling
bodies:
  - {name: pinion, q0: [0.076, 0.218, 0]}
joints:
  - {type: rack_pinion, i: ground, si: [0.1, 0.2], vi: [3, 4], j: pinion, rj: 0.03}
drivers:
  - {type: absolute_angle, body: pinion, f: "1.5*t + sin(t)"}
)Y";
  const Run run = analyze(yaml, {0, 20, 1000});
  const double rj = 0.03, ux = 0.6, uy = 0.8;
  Error e;
  for (const auto& r : run.rows) {
    const double t = r.t, phi = 1.5 * t + std::sin(t), w = 1.5 + std::cos(t), al = -std::sin(t);
    const double s = -rj * phi;
    e.add(e.q, r.q[0], 0.1 + s * ux - rj * uy);
    e.add(e.q, r.q[1], 0.2 + s * uy + rj * ux);
    e.add(e.qd, r.qd[0], -rj * w * ux);
    e.add(e.qd, r.qd[1], -rj * w * uy);
    e.add(e.qdd, r.qdd[0], -rj * al * ux);
    e.add(e.qdd, r.qdd[1], -rj * al * uy);
  }
  INFO("relative errors q " << e.q << ", qd " << e.qd << ", qdd " << e.qdd);
  CHECK(e.q <= 16 * kEps);
  CHECK(e.qd <= 16 * kEps);
  CHECK(e.qdd <= 16 * kEps);
}

TEST_CASE("gears: a welded body moves as part of the other", "[gears]") {
  // b is welded to a at a's [0.4, 0] and b's [-0.1, 0.05], turned by 0.5; a turns about the
  // origin by theta = 0.8 t + 0.3 sin 2t. Then r_b = A(th) [0.4, 0] - A(th + 0.5) [-0.1, 0.05].
  const std::string yaml = R"Y(name: weld
bodies:
  - {name: a, q0: [0, 0, 0]}
  - {name: b, q0: [0.5, 0, 0.5]}
joints:
  - {type: revolute, i: ground, j: a}
  - {type: fixed, i: a, j: b, si: [0.4, 0], sj: [-0.1, 0.05], angle: 0.5}
drivers:
  - {type: absolute_angle, body: a, f: "0.8*t + 0.3*sin(2*t)"}
)Y";
  const Run run = analyze(yaml, {0, 10, 400});
  Error e;
  for (const auto& r : run.rows) {
    const double t = r.t, th = 0.8 * t + 0.3 * std::sin(2 * t), w = 0.8 + 0.6 * std::cos(2 * t),
                 al = -1.2 * std::sin(2 * t);
    const double c = std::cos(th), s = std::sin(th), cb = std::cos(th + 0.5),
                 sb = std::sin(th + 0.5);
    // v = r_b, a vector fixed in a: dv/dt = w J v, d2v/dt2 = al J v - w^2 v.
    const double vx = 0.4 * c - (-0.1 * cb - 0.05 * sb), vy = 0.4 * s - (-0.1 * sb + 0.05 * cb);
    e.add(e.q, r.q[3], vx);
    e.add(e.q, r.q[4], vy);
    e.add(e.q, r.q[5], th + 0.5);
    e.add(e.qd, r.qd[3], -w * vy);
    e.add(e.qd, r.qd[4], w * vx);
    e.add(e.qd, r.qd[5], w);
    e.add(e.qdd, r.qdd[3], -al * vy - w * w * vx);
    e.add(e.qdd, r.qdd[4], al * vx - w * w * vy);
    e.add(e.qdd, r.qdd[5], al);
  }
  INFO("relative errors q " << e.q << ", qd " << e.qd << ", qdd " << e.qdd);
  CHECK(e.q <= 16 * kEps);
  CHECK(e.qd <= 16 * kEps);
  CHECK(e.qdd <= 16 * kEps);
}

TEST_CASE("gears: the 40-digit reference agrees with the double analysis on the planetary train",
          "[gears][reference]") {
  const auto model = kc::CompiledModel::from_file(source_dir() + "/examples/gears/planetary.yaml");
  const kc::TimeGrid grid{0, 4, 80};  // one carrier turn
  const Run run = analyze(*model, grid);
  std::vector<kc::StateRow> ref;
  kc::run_reference_analysis(*model, grid, 40, [&](const kc::StateRow& r) { ref.push_back(r); });
  REQUIRE(ref.size() == run.rows.size());
  Error e;
  for (std::size_t k = 0; k < ref.size(); ++k)
    for (int c = 0; c < model->nq(); ++c) {
      e.add(e.q, run.rows[k].q[c], ref[k].q[c]);
      e.add(e.qd, run.rows[k].qd[c], ref[k].qd[c]);
      e.add(e.qdd, run.rows[k].qdd[c], ref[k].qdd[c]);
    }
  INFO("relative to the reference: q " << e.q << ", qd " << e.qd << ", qdd " << e.qdd);
  CHECK(e.q <= 64 * kEps);
  CHECK(e.qd <= 64 * kEps);
  CHECK(e.qdd <= 64 * kEps);
}

namespace {

// The generated model stepped over `grid` from q0, against the in-process analysis.
template <class M>
double generated_against_analyze(const std::string& file, const kc::TimeGrid& grid) {
  const auto model = kc::CompiledModel::from_file(file);
  const Run run = analyze(*model, grid);
  typename M::Params p{};
  double q[M::nq], qd[M::nq] = {}, qdd[M::nq] = {};
  for (int k = 0; k < M::nq; ++k) q[k] = M::q0[k];
  double worst = 0;
  for (const auto& r : run.rows) {
    const auto report = M::solve_step(q, r.t, p, qd, qdd, typename M::BlockOptions{});
    REQUIRE(report.status == 0);
    for (int c = 0; c < M::nq; ++c) {
      worst = std::max(worst, std::abs(q[c] - r.q[c]) / (1 + std::abs(r.q[c])));
      worst = std::max(worst, std::abs(qd[c] - r.qd[c]) / (1 + std::abs(r.qd[c])));
      worst = std::max(worst, std::abs(qdd[c] - r.qdd[c]) / (1 + std::abs(r.qdd[c])));
    }
  }
  return worst;
}

}  // namespace

TEST_CASE("gears: the generated headers agree with analyze", "[gears][generated]") {
  const double pair = generated_against_analyze<km::gear_pair>(
      source_dir() + "/tests/mechanisms/gear_pair.yaml", {0, 10, 500});
  const double planetary = generated_against_analyze<km::planetary>(
      source_dir() + "/examples/gears/planetary.yaml", {0, 8, 480});
  INFO("largest relative difference: gear_pair " << pair << ", planetary " << planetary);
  CHECK(pair <= 1e-12);
  CHECK(planetary <= 1e-12);
}

TEST_CASE("gears: the mesh reaction and the motor torque of a gear pair with inertias",
          "[gears][forces]") {
  // gear_pair.yaml: J_p 0.001, J_w 0.02, alpha_p = 2, alpha_w = -(ri/rj) alpha_p. The mesh
  // turns the wheel with J_w alpha_w (mesh.tz, about its centre), by a tangential force
  // J_w alpha_w / -rj at the pitch point (mesh.fy; the line of centres is along x); the motor
  // supplies J_p alpha_p + (ri/rj)^2 J_w alpha_p.
  using M = km::gear_pair;
  const double ri = 0.03, rj = 0.075, jp = 0.001, jw = 0.02, ap = 2, aw = -(ri / rj) * ap;
  const auto model =
      kc::CompiledModel::from_file(source_dir() + "/tests/mechanisms/gear_pair.yaml");
  const kc::ForceModel forces = kc::forces_for_analysis(*model);
  kc::ForceSolver solver(*model, forces);
  const auto names = kc::force_columns(model->mechanism());
  REQUIRE(names.size() == static_cast<std::size_t>(M::num_force_columns));
  const auto column = [&](const std::string& n) {
    return static_cast<int>(std::find(names.begin(), names.end(), n) - names.begin());
  };
  const int effort = column("motor.effort"), fx = column("mesh.fx"), fy = column("mesh.fy"),
            tz = column("mesh.tz"), bearing = column("wheel_bearing.fy");
  REQUIRE(tz < static_cast<int>(names.size()));
  const Run run = analyze(*model, {0, 10, 200});
  const M::Params p{};
  double worst = 0, generated = 0;
  for (const auto& r : run.rows) {
    std::vector<double> cols;
    REQUIRE(solver.solve(r.t, r.q, r.qd, r.qdd, cols));
    const double truth[] = {jp * ap + (ri / rj) * (ri / rj) * jw * ap, 0, -jw * aw / rj, jw * aw,
                            jw * aw / rj};
    const int at[] = {effort, fx, fy, tz, bearing};
    for (int k = 0; k < 5; ++k) worst = std::max(worst, std::abs(cols[at[k]] - truth[k]));
    double lambda[M::nc], gcols[M::num_force_columns];
    REQUIRE(
        M::solve_forces(r.q.data(), r.qd.data(), r.qdd.data(), r.t, p, lambda, M::BlockOptions{})
            .status == 0);
    M::force_columns(r.q.data(), r.t, p, lambda, gcols);
    for (int c = 0; c < M::num_force_columns; ++c)
      generated = std::max(generated, std::abs(gcols[c] - cols[c]));
  }
  INFO("largest error against the closed form " << worst << ", generated against analyze "
                                                << generated << " (forces ~ 0.2)");
  const double scale = jw * std::abs(aw) / rj;  // the largest column, 0.21
  CHECK(worst <= 32 * kEps * scale);
  CHECK(generated <= 32 * kEps * scale);
}

namespace {

// A gear pair, each key on its own line so a case can name the line it breaks.
const std::string kPair = R"Y(name: pair
bodies:
  - name: a
    q0: [0, 0, 0]
  - name: b
    q0: [0.3, 0, 0]
joints:
  - type: revolute
    i: ground
    j: a
  - type: revolute
    i: ground
    j: b
    si: [0.3, 0]
  - type: gear
    name: mesh
    i: a
    j: b
    ri: 0.1
    rj: 0.2
drivers:
  - type: absolute_angle
    body: a
    f: t
)Y";

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  return text.replace(at, from.size(), to);
}

int line_of(const std::string& text, const std::string& what) {
  const auto at = text.find(what);
  REQUIRE(at != std::string::npos);
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
}

fs::path scratch(const std::string& name) { return kinegen::test::scratch_dir("gears", name); }

kinegen::test::CommandResult analyze_file(const fs::path& mech, const fs::path& csv) {
  return kinegen::test::run_command({KINEGEN_EXE, "analyze", mech.string(), "--t0", "0", "--t1",
                                     "1", "--steps", "4", "-o", csv.string()});
}

}  // namespace

TEST_CASE("gears: hostile keys give one error line with the YAML line, exit 2, no output",
          "[gears][hostile]") {
  const std::string internal = replaced(replaced(kPair, "si: [0.3, 0]", "si: [0.1, 0]"), "rj: 0.2",
                                        "rj: 0.2\n    internal: true");
  const std::string rack = R"Y(name: rack
bodies:
  - name: p
    q0: [0, 0.1, 0]
joints:
  - type: rack_pinion
    i: ground
    vi: [1, 0]
    j: p
    rj: -0.1
drivers:
  - type: absolute_angle
    body: p
    f: t
)Y";
  struct Case {
    const char* name;
    std::string text;
    std::string at;       // text on the line the message must name
    const char* message;  // a phrase of it
  };
  const std::vector<Case> cases = {
      {"negative_ri", replaced(kPair, "ri: 0.1", "ri: -0.1"), "ri: -0.1", "must be > 0"},
      {"zero_rj", replaced(kPair, "rj: 0.2", "rj: 0"), "rj: 0", "must be > 0"},
      {"internal_small_ring", replaced(internal, "rj: 0.2", "rj: 0.1"), "rj: 0.1", "needs rj > ri"},
      {"missing_rj", replaced(kPair, "    rj: 0.2\n", ""), "type: gear", "missing key 'rj'"},
      {"unknown_key", replaced(kPair, "rj: 0.2", "rj: 0.2\n    radius: 1"), "radius: 1",
       "unknown key 'radius'"},
      {"internal_not_bool", replaced(internal, "internal: true", "internal: maybe"),
       "internal: maybe", "expected true or false"},
      {"rack_negative_rj", rack, "rj: -0.1", "must be > 0"},
      {"rack_missing_vi", replaced(rack, "    vi: [1, 0]\n", ""), "type: rack_pinion",
       "missing key 'vi'"},
  };
  for (const Case& c : cases) {
    SECTION(c.name) {
      const fs::path dir = scratch(c.name);
      const fs::path mech = dir / "m.yaml", csv = dir / "m.csv";
      std::ofstream(mech) << c.text;
      const auto r = analyze_file(mech, csv);
      INFO(r.err);
      CHECK(r.exit_code == 2);
      const std::string where =
          "error: " + mech.string() + ":" + std::to_string(line_of(c.text, c.at)) + ": ";
      CHECK(r.err.rfind(where, 0) == 0);
      CHECK(r.err.find(c.message) != std::string::npos);
      CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
      CHECK(r.out.empty());
      CHECK_FALSE(fs::exists(csv));
    }
  }
  // The same pair with valid keys analyzes (the cases above break only what they say).
  for (const std::string& text : {kPair, internal, replaced(rack, "rj: -0.1", "rj: 0.1")}) {
    const fs::path dir = scratch("valid");
    std::ofstream(dir / "m.yaml") << text;
    const auto r = analyze_file(dir / "m.yaml", dir / "m.csv");
    INFO(text << r.err);
    CHECK(r.exit_code == 0);
    CHECK(r.err.empty());
  }
}

TEST_CASE("gears: a centre distance off the pitch radii is one warning at assembly", "[gears]") {
  struct Case {
    const char* name;
    std::string text;
    const char* message;  // a phrase of the warning; nullptr: none
  };
  // The ring b about [0.1, 0] (rj - ri = 0.1 from a's centre, along psi = 0 with c = 0).
  const std::string internal = replaced(replaced(kPair, "si: [0.3, 0]", "si: [0.1, 0]"), "rj: 0.2",
                                        "rj: 0.2\n    internal: true");
  const std::vector<Case> cases = {
      {"external_ok", kPair, nullptr},
      {"external_off", replaced(kPair, "si: [0.3, 0]", "si: [0.31, 0]"),
       "the centre distance is 0.31, not ri + rj = 0.3"},
      {"internal_ok", internal, nullptr},
      {"internal_off", replaced(internal, "si: [0.1, 0]", "si: [0.12, 0]"),
       "the centre distance is 0.12, not rj - ri = 0.1"},
      {"half_a_turn", replaced(kPair, "rj: 0.2", "rj: 0.2\n    c: \"0.3*pi\""),
       "points against psi"},
  };
  for (const Case& c : cases) {
    SECTION(c.name) {
      const fs::path dir = scratch(c.name);
      const fs::path mech = dir / "m.yaml", csv = dir / "m.csv";
      std::ofstream(mech) << c.text;
      const auto r = analyze_file(mech, csv);
      INFO(r.err);
      CHECK(r.exit_code == 0);
      if (!c.message) {
        CHECK(r.err.empty());
        continue;
      }
      const std::string where = "warning: " + mech.string() + ":" +
                                std::to_string(line_of(c.text, "type: gear")) +
                                ": joints[2] 'mesh' (gear): ";
      CHECK(r.err.rfind(where, 0) == 0);
      CHECK(r.err.find(c.message) != std::string::npos);
      CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    }
  }
}

TEST_CASE("gears: power balance on the planetary train, steady and with a varying sun speed",
          "[gears][forces]") {
  // examples/gears/planetary.yaml (inertias on sun, carrier and planet, the planet's mass),
  // as it is and with the sun driven at a varying speed: on every row the motor's power,
  // effort times the sun's rate, equals dKE/dt written out from the file's masses and the
  // rows' kinematics (no gravity, no loads; the meshes do no work).
  std::ifstream in(source_dir() + "/examples/gears/planetary.yaml");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string drive = "f: \"omega*t\"";
  REQUIRE(text.find(drive) != std::string::npos);
  std::string varying = text;
  varying.replace(varying.find(drive), drive.size(), "f: \"omega*t + 0.5*sin(3*t)\"");
  for (const std::string& yaml : {text, varying}) {
    const auto model =
        kc::CompiledModel::from_mechanism(kc::parse_mechanism(yaml, "planetary.yaml"));
    const auto forces = kc::forces_for_analysis(*model);
    kc::ForceSolver solver(*model, forces);
    double worst = 0, largest = 0;
    kc::run_analysis(*model, {0, 2, 400}, [&](const kc::StateRow& r) {
      std::vector<double> columns;
      REQUIRE(solver.solve(r.t, r.q, r.qd, r.qdd, columns));
      // sun J 2e-6 (q 0..2), carrier J 5e-6 (3..5), planet m 0.05, J 1e-5 (6..8), com at origin.
      const double kinetic_rate = 2e-6 * r.qd[2] * r.qdd[2] + 5e-6 * r.qd[5] * r.qdd[5] +
                                  0.05 * (r.qd[6] * r.qdd[6] + r.qd[7] * r.qdd[7]) +
                                  1e-5 * r.qd[8] * r.qdd[8];
      const double power = columns[0] * r.qd[2];
      worst = std::max(worst, std::abs(power - kinetic_rate));
      largest = std::max(largest, std::abs(power) + std::abs(kinetic_rate));
    });
    INFO("worst " << worst << " W of " << largest << " W");
    CHECK(worst <= 1e-10 * std::max(largest, 1e-6));
  }
}
