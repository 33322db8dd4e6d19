// Spatial files (docs/format.md, Spatial mechanisms), kinematics through eval and check: the
// homogeneous A(p) against Eigen's quaternions, every joint type's Phi_q against central
// differences and gamma against the derivative of Phi_q qd - nu along a path (at Euler
// parameters off the unit sphere, where the other form of A(p) gives another gamma), the
// normalization row's gamma, the revolute_angle's sign, `check`, and the refusals.
#include <Eigen/Geometry>
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "support/cli.hpp"
#include "support/files.hpp"

namespace {

namespace kc = kinegen::codegen;

std::string mechanism(const std::string& name) {
  return std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/" + name + ".yaml";
}

std::unique_ptr<kc::CompiledModel> spatial_model(const std::string& path) {
  kc::BuildOptions build;
  build.spatial = true;
  return kc::CompiledModel::from_file(path, {}, build);
}

using kinegen::test::kinegen_cli;

// A unit quaternion's Euler parameters [e0, e1, e2, e3].
Eigen::Vector4d euler(const Eigen::Quaterniond& r) { return {r.w(), r.x(), r.y(), r.z()}; }

// The slider-crank's q with body b (0 crank, 1 rod, 2 slider) at r and rotation `rot`.
void place(Eigen::VectorXd& q, int b, const Eigen::Vector3d& r, const Eigen::Quaterniond& rot) {
  q.segment<3>(7 * b) = r;
  q.segment<4>(7 * b + 3) = euler(rot);
}

TEST_CASE("spatial: a spherical joint's residual is the homogeneous A(p) of Eigen's rotation",
          "[spatial]") {
  const auto model = spatial_model(mechanism("spatial_slider_crank"));
  REQUIRE(model->nq() == 21);
  REQUIRE(model->nc() == 5 + 3 + 4 + 5 + 1 + 3);  // joints, the driver, euler_<body>
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::VectorXd q = model->q0();
    const Eigen::Quaterniond crank = Eigen::Quaterniond::UnitRandom();
    const Eigen::Quaterniond rod = Eigen::Quaterniond::UnitRandom();
    const Eigen::Vector3d rc(u(rng), u(rng), u(rng)), rr(u(rng), u(rng), u(rng));
    place(q, 0, rc, crank);
    place(q, 1, rr, rod);
    const kc::EvalResult e = kc::evaluate(*model, q, Eigen::VectorXd::Zero(21), 0.1);
    // Rows 5..7: the spherical joint, d = r_rod + A_rod 0 - r_crank - A_crank [0, 0, 0.08].
    const Eigen::Vector3d d = rr - rc - crank.toRotationMatrix() * Eigen::Vector3d(0, 0, 0.08);
    for (int k = 0; k < 3; ++k) CHECK(std::abs(e.phi[5 + k] - d[k]) < 1e-15);
    // The normalization rows are 0 at unit p.
    for (int r = 18; r < 21; ++r) CHECK(std::abs(e.phi[r]) < 1e-15);
  }
}

TEST_CASE("spatial: the revolute_angle measures the right-hand rotation about axis_i",
          "[spatial]") {
  const auto model = spatial_model(mechanism("spatial_slider_crank"));
  const double theta = 0.7, omega = 6;
  Eigen::VectorXd q = model->q0();
  place(q, 0, {0, 0.1, 0.12},
        Eigen::Quaterniond(Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitX())));
  const Eigen::VectorXd qd = Eigen::VectorXd::Zero(21);
  // Row 17: the driver (after 17 joint rows). The crank turned by +theta about x meets f = theta.
  CHECK(std::abs(kc::evaluate(*model, q, qd, theta / omega).phi[17]) < 1e-15);
  CHECK(std::abs(kc::evaluate(*model, q, qd, -theta / omega).phi[17]) > 0.5);
  // At the q0 pose (every body as the file places it) and t = 0, every row holds.
  const kc::EvalResult at_q0 = kc::evaluate(*model, model->q0(), qd, 0);
  CHECK(at_q0.phi.cwiseAbs().maxCoeff() < 1e-15);
}

// g(s) = Phi_q(q + s qd, t + s) qd - nu(q + s qd, t + s) has g'(0) = -gamma(q, qd, t).
TEST_CASE("spatial: every type's Phi_q and gamma against differences along a path", "[spatial]") {
  const auto model = spatial_model(mechanism("spatial_all_types"));
  const int nq = model->nq(), nc = model->nc();
  REQUIRE(nq == 21);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 4; ++trial) {
    Eigen::VectorXd q = model->q0(), qd(nq);
    for (int k = 0; k < nq; ++k) {
      q[k] += 0.2 * u(rng);  // Euler parameters off the unit sphere too
      qd[k] = u(rng);
    }
    const double t = 0.3 + 0.5 * u(rng);
    const kc::EvalResult e = kc::evaluate(*model, q, qd, t);
    // Phi_q against central differences of Phi.
    const double h = 1e-6;
    double worst_jac = 0;
    for (int k = 0; k < nq; ++k) {
      Eigen::VectorXd qp = q, qm = q;
      qp[k] += h;
      qm[k] -= h;
      const Eigen::VectorXd fd =
          (kc::evaluate(*model, qp, qd, t).phi - kc::evaluate(*model, qm, qd, t).phi) / (2 * h);
      worst_jac = std::max(worst_jac, (fd - e.phi_q.col(k)).cwiseAbs().maxCoeff());
    }
    CHECK(worst_jac < 1e-8);
    // gamma against the derivative of Phi_q qd - nu along the path.
    const auto g = [&](double s) {
      const kc::EvalResult a = kc::evaluate(*model, q + s * qd, qd, t + s);
      return Eigen::VectorXd(a.phi_q * qd - a.nu);
    };
    const double hs = 1e-5;
    const Eigen::VectorXd derivative = (g(hs) - g(-hs)) / (2 * hs);
    REQUIRE(e.gamma.size() == nc);
    for (int r = 0; r < nc; ++r) {
      INFO("row " << r << " (" << model->row_label(r) << ")");
      CHECK(std::abs(derivative[r] + e.gamma[r]) < 1e-7 * std::max(1.0, std::abs(e.gamma[r])));
    }
    // The normalization rows (last three): gamma = -2 pdot^T pdot exactly as derived.
    for (int b = 0; b < 3; ++b) {
      const double pp = qd.segment<4>(7 * b + 3).squaredNorm();
      CHECK(std::abs(e.gamma[nc - 3 + b] + 2 * pp) < 1e-14 * std::max(1.0, pp));
      CHECK(e.nu[nc - 3 + b] == 0);
    }
  }
}

TEST_CASE("spatial: check passes on the spatial test mechanisms", "[spatial]") {
  for (const char* name : {"spatial_slider_crank", "spatial_all_types"}) {
    const auto r = kinegen_cli({"check", mechanism(name)});
    INFO(name << "\n" << r.out << r.err);
    CHECK(r.exit_code == 0);
  }
  const auto e = kinegen_cli({"eval", mechanism("spatial_slider_crank")});
  CHECK(e.exit_code == 0);
  CHECK(e.out.find("\"gamma\"") != std::string::npos);
}

struct BadCase {
  const char* what;
  std::string yaml;
  int line;
  const char* says;
};

const char* const kHead = "space: 3d\nname: bad\nbodies:\n";

TEST_CASE("spatial: bad input is one error line naming the item and its line, exit 2",
          "[spatial]") {
  const std::string two =
      std::string(kHead) + "  - {name: a, r0: [0, 0, 0]}\n" + "  - {name: b, r0: [1, 0, 0]}\n";
  const std::vector<BadCase> cases = {
      {"p0 = 0", std::string(kHead) + "  - {name: a, p0: [0, 0, 0, 0]}\n", 4, "Euler parameters"},
      {"two orientations",
       std::string(kHead) + "  - {name: a, p0: [1, 0, 0, 0], rot0: {axis: [1, 0, 0], angle: 0}}\n",
       4, "one of q0, p0 and rot0"},
      {"a zero axis",
       two + "joints:\n  - {type: revolute, i: a, j: b, axis_i: [0, 0, 0], axis_j: [1, 0, 0]}\n", 7,
       "axis must not be zero"},
      {"parallel universal",
       two +
           "joints:\n  - {type: universal, i: a, j: b, axis_i: [1, 0, 0], axis_j: [1, 0, 0.001]}\n",
       7, "parallel"},
      {"revolute_angle on a spherical joint",
       two + "joints:\n  - {type: spherical, name: ball, i: a, j: b}\ndrivers:\n  - {type: "
             "revolute_angle, joint: ball, f: t}\n",
       9, "revolute or cylindrical"},
      {"free in a spatial file", two + "free:\n  - {type: absolute_x, body: a}\n", 7,
       "not supported in spatial files"},
      {"a planar q0", std::string(kHead) + "  - {name: a, q0: [0, 0, 0]}\n", 4, "7 numbers"},
      {"vi",
       two + "joints:\n  - {type: translational, i: a, j: b, vi: [1, 0, 0], axis_i: [1, 0, 0], "
             "axis_j: [1, 0, 0]}\n",
       7, "unknown key 'vi'"},
      {"a planar type", two + "joints:\n  - {type: gear, i: a, j: b}\n", 7, "only in planar files"},
      {"a 2-vector", two + "joints:\n  - {type: spherical, i: a, j: b, si: [0, 0]}\n", 7,
       "3 numbers"},
      {"a non-finite hardpoint",
       two + "joints:\n  - {type: spherical, i: a, j: b, si: [1e999, 0, 0]}\n", 7,
       "not a finite number"},
      {"r0 in a planar file", "name: bad\nbodies:\n  - {name: a, q0: [0, 0, 0], r0: [0, 0, 0]}\n",
       3, "spatial files"},
      {"vectors in a planar file",
       "name: bad\nbodies:\n  - {name: a, q0: [0, 0, 0]}\nvectors: []\n", 4, "spatial files"},
      {"space: 4d", "space: 4d\nname: bad\nbodies:\n  - {name: a, q0: [0, 0, 0]}\n", 1, "2d"},
  };
  const auto dir = kinegen::test::scratch_dir("spatial", "bad_input");
  for (const BadCase& c : cases) {
    INFO(c.what << "\n" << c.yaml);
    const auto path = dir / "bad.yaml";
    kinegen::test::write_text(path, c.yaml);
    const auto r = kinegen_cli({"eval", path.string()});
    INFO(r.err);
    CHECK(r.exit_code == 2);
    CHECK(r.err.rfind("error: ", 0) == 0);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(r.err.find(":" + std::to_string(c.line) + ":") != std::string::npos);
    CHECK(r.err.find(c.says) != std::string::npos);
  }
}

TEST_CASE("spatial: commands without spatial support refuse a spatial file, exit 2", "[spatial]") {
  const std::string file = mechanism("spatial_slider_crank");
  const auto out = kinegen::test::scratch_dir("spatial", "refused");
  const std::vector<std::string> run = {"--t0", "0", "--t1", "1", "--steps", "2"};
  const auto with_run = [&](std::vector<std::string> args) {
    args.insert(args.end(), run.begin(), run.end());
    return args;
  };
  const std::vector<std::vector<std::string>> commands = {
      with_run({"simulate", file}),
      {"equilibrium", file},
      {"modes", file},
      {"linearize", file},
      with_run({"animate", file, "-o", (out / "a.svg").string()}),
  };
  for (const auto& args : commands) {
    const auto r = kinegen_cli(args);
    INFO(args[0] << ": " << r.err);
    CHECK(r.exit_code == 2);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(r.err.find("spatial files (space: 3d) are not supported by `kinegen " + args[0] + "`") !=
          std::string::npos);
  }
  CHECK(std::filesystem::is_empty(out));
}

}  // namespace
