// `analyze` on spatial files (docs/format.md, Spatial mechanisms): the spatial slider-crank's
// slider, crank pin, crank axle vector and angular velocities against the closed form
// x(theta) = sqrt(0.09 - (0.1 - 0.08 sin theta)^2 - (0.12 + 0.08 cos theta)^2) and its
// derivatives, unit Euler parameters, a start at t0 = 0.3 on the assembly the q0 pose shows
// (not mirrored), the branch check, and the options refused on a spatial file.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdlib>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "support/cli.hpp"
#include "support/csv_columns.hpp"
#include "support/files.hpp"

namespace {

std::string mechanism(const std::string& name) {
  return std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/" + name + ".yaml";
}

using kinegen::test::kinegen_cli;

// The slider's x, dx/dtheta and d2x/dtheta2 (x^2 = u(theta)).
struct Slider {
  double x, dx, ddx;
};
Slider slider(double th) {
  const double y = 0.1 - 0.08 * std::sin(th), z = 0.12 + 0.08 * std::cos(th);
  const double y1 = -0.08 * std::cos(th), z1 = -0.08 * std::sin(th);
  const double y2 = 0.08 * std::sin(th), z2 = -0.08 * std::cos(th);
  const double u = 0.09 - y * y - z * z, u1 = -2 * (y * y1 + z * z1),
               u2 = -2 * (y1 * y1 + y * y2 + z1 * z1 + z * z2);
  const double x = std::sqrt(u), x1 = u1 / (2 * x);
  return {x, x1, (u2 - 2 * x1 * x1) / (2 * x)};
}

TEST_CASE("spatial analyze: the slider-crank against its closed form", "[spatial]") {
  const double omega = 6;
  for (const char* t0 : {"0", "0.3"}) {
    const auto r = kinegen_cli(
        {"analyze", mechanism("spatial_slider_crank"), "--t0", t0, "--t1", "1.3", "--steps", "40"});
    INFO("t0 " << t0 << "\n" << r.err);
    REQUIRE(r.exit_code == 0);
    auto c = kinegen::test::csv_columns(r.out);
    const auto& t = c["t"];
    REQUIRE(t.size() == 41);
    double worst_x = 0, worst_v = 0, worst_a = 0, worst_p = 0, worst_unit = 0, worst_rot = 0;
    for (std::size_t k = 0; k < t.size(); ++k) {
      const double th = omega * t[k];
      const Slider s = slider(th);
      worst_x = std::max(worst_x, std::abs(c["slider.x"][k] - s.x));
      worst_x = std::max(worst_x, std::abs(c["S.x"][k] - s.x));
      worst_x = std::max(worst_x, std::abs(c["slider_x"][k] - s.x));
      // Outputs of a point's and a vector's global components.
      worst_x = std::max(worst_x, std::abs(c["pin_y"][k] - (0.1 - 0.08 * std::sin(th))));
      worst_x = std::max(worst_x, std::abs(c["axle_z"][k] - std::cos(th)));
      worst_v = std::max(worst_v, std::abs(c["slider.vx"][k] - s.dx * omega));
      worst_v = std::max(worst_v, std::abs(c["slider_x.v"][k] - s.dx * omega));
      worst_a = std::max(worst_a, std::abs(c["slider.ax"][k] - s.ddx * omega * omega));
      // The crank pin, its velocity and acceleration; the axle vector [0, 0, 1] of the crank.
      const double pin[] = {0, 0.1 - 0.08 * std::sin(th), 0.12 + 0.08 * std::cos(th)};
      const double pin_v[] = {0, -0.08 * omega * std::cos(th), -0.08 * omega * std::sin(th)};
      const double pin_a[] = {0, 0.08 * omega * omega * std::sin(th),
                              -0.08 * omega * omega * std::cos(th)};
      const double axle[] = {0, -std::sin(th), std::cos(th)};
      const double axle_v[] = {0, -omega * std::cos(th), -omega * std::sin(th)};
      const char* xyz[] = {"x", "y", "z"};
      for (int i = 0; i < 3; ++i) {
        const std::string a = xyz[i];
        worst_p = std::max(worst_p, std::abs(c["P." + a][k] - pin[i]));
        worst_v = std::max(worst_v, std::abs(c["P.v" + a][k] - pin_v[i]));
        worst_a = std::max(worst_a, std::abs(c["P.a" + a][k] - pin_a[i]));
        worst_rot = std::max(worst_rot, std::abs(c["axle." + a][k] - axle[i]));
        worst_rot = std::max(worst_rot, std::abs(c["axle.v" + a][k] - axle_v[i]));
      }
      // The crank turns at omega about x: omega = 2 E pdot, alpha = 0.
      worst_rot = std::max(worst_rot, std::abs(c["crank.wx"][k] - omega));
      worst_rot = std::max({worst_rot, std::abs(c["crank.wy"][k]), std::abs(c["crank.wz"][k]),
                            std::abs(c["crank.alphax"][k])});
      for (const char* b : {"crank", "rod", "slider"}) {
        double pp = 0;
        for (const char* e : {".e0", ".e1", ".e2", ".e3"})
          pp += std::pow(c[b + std::string(e)][k], 2);
        worst_unit = std::max(worst_unit, std::abs(pp - 1));
      }
    }
    CHECK(worst_x < 1e-12 * 0.3);
    CHECK(worst_p < 1e-12 * 0.3);
    CHECK(worst_v < 1e-11 * 0.3 * omega);
    CHECK(worst_a < 1e-10 * 0.3 * omega * omega);
    CHECK(worst_rot < 1e-11 * omega * omega);
    CHECK(worst_unit < 1e-13);
    WARN("t0 " << t0 << ": x " << worst_x << ", point " << worst_p << ", v " << worst_v << ", a "
               << worst_a << ", rotation " << worst_rot << ", |p|^2 - 1 " << worst_unit);
  }
}

TEST_CASE("spatial analyze: options without spatial support are refused", "[spatial]") {
  const std::string file = mechanism("spatial_slider_crank");
  for (const char* option : {"--forces", "--reference-digits=30"}) {
    const auto r = kinegen_cli({"analyze", file, "--t0", "0", "--t1", "1", "--steps", "2", option});
    INFO(option << ": " << r.err);
    CHECK(r.exit_code == 2);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(r.err.find("not supported by `kinegen analyze --") != std::string::npos);
  }
}

TEST_CASE("spatial analyze: a solve off a hinge's branch is exit 1 naming it", "[spatial]") {
  // The bearing's axis_j reversed: its rows hold with the axes opposed, its branch does not.
  std::string text = kinegen::test::read_text(mechanism("spatial_slider_crank"));
  const std::string axis = "axis_i: [1, 0, 0], axis_j: [1, 0, 0]}";
  text.replace(text.find(axis), axis.size(), "axis_i: [1, 0, 0], axis_j: [-1, 0, 0]}");
  const auto dir = kinegen::test::scratch_dir("spatial", "branch");
  kinegen::test::write_text(dir / "reversed.yaml", text);
  const auto r = kinegen_cli(
      {"analyze", (dir / "reversed.yaml").string(), "--t0", "0", "--t1", "1", "--steps", "4"});
  INFO(r.err);
  CHECK(r.exit_code == 1);
  CHECK(r.err.find("'bearing'") != std::string::npos);
  CHECK(r.err.find("left its branch (axis_i . axis_j") != std::string::npos);
}

TEST_CASE("spatial analyze: a slider turned end for end is off its branch", "[spatial]") {
  // The guide's axis_j reversed: all five rows hold (ref_j follows the reversed axis at the q0
  // pose, so the lock holds too), and only the axes' check catches it.
  std::string text = kinegen::test::read_text(mechanism("spatial_slider_crank"));
  const std::string axis =
      "si: [0, 0, 0], sj: [0, 0, 0],\n     axis_i: [1, 0, 0], axis_j: [1, 0, 0]}";
  REQUIRE(text.find(axis) != std::string::npos);
  text.replace(text.find(axis), axis.size(),
               "si: [0, 0, 0], sj: [0, 0, 0],\n     axis_i: [1, 0, 0], axis_j: [-1, 0, 0]}");
  const auto dir = kinegen::test::scratch_dir("spatial", "slider_branch");
  kinegen::test::write_text(dir / "reversed.yaml", text);
  const auto r = kinegen_cli(
      {"analyze", (dir / "reversed.yaml").string(), "--t0", "0", "--t1", "1", "--steps", "4"});
  INFO(r.err);
  CHECK(r.exit_code == 1);
  CHECK(r.err.find("translational") != std::string::npos);
  CHECK(r.err.find("left its branch (axis_i . axis_j") != std::string::npos);
}

TEST_CASE("atan2 in outputs: every quadrant and the x axis, with exact rates", "[spatial]") {
  // A point driven once round the unit circle: atan2(y, x) is the angle t wrapped to (-pi, pi],
  // its rate 1 and its acceleration 0; atan2(0, x) is 0 or pi by the side.
  const auto dir = kinegen::test::scratch_dir("spatial", "atan2");
  kinegen::test::write_text(dir / "circle.yaml", R"yaml(name: circle
bodies:
  - {name: b, q0: [1, 0, 0]}
drivers:
  - {type: absolute_x, body: b, f: "cos(t)"}
  - {type: absolute_y, body: b, f: "sin(t)"}
  - {type: absolute_angle, body: b, f: "0"}
outputs:
  angle: "atan2(y_b, x_b)"
  side: "atan2(0, x_b)"
)yaml");
  const auto r = kinegen_cli({"analyze", (dir / "circle.yaml").string(), "--t0", "0.05", "--t1",
                              "6.25", "--steps", "62"});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  auto c = kinegen::test::csv_columns(r.out);
  const double pi = std::acos(-1.0);
  for (std::size_t k = 0; k < c["t"].size(); ++k) {
    const double t = c["t"][k];
    CAPTURE(t);
    CHECK(std::abs(c["angle"][k] - std::atan2(std::sin(t), std::cos(t))) < 1e-14);
    CHECK(std::abs(c["angle.v"][k] - 1) < 1e-9);
    CHECK(std::abs(c["angle.a"][k]) < 1e-8);
    CHECK(c["side"][k] == (std::cos(t) < 0 ? pi : 0.0));
  }
  }

TEST_CASE("spatial analyze: an undriven file names both counts", "[spatial]") {
  std::string text = kinegen::test::read_text(mechanism("spatial_slider_crank"));
  const std::string driver = "  - {type: revolute_angle, joint: bearing, f: \"omega*t\"}\n";
  REQUIRE(text.find(driver) != std::string::npos);
  text.replace(text.find(driver), driver.size(), "");
  const auto dir = kinegen::test::scratch_dir("spatial", "undriven");
  kinegen::test::write_text(dir / "undriven.yaml", text);
  const auto r = kinegen_cli(
      {"analyze", (dir / "undriven.yaml").string(), "--t0", "0", "--t1", "1", "--steps", "4"});
  INFO(r.err);
  CHECK(r.exit_code == 2);
  CHECK(r.err.find("20 equations for 21 coordinates") != std::string::npos);
  CHECK(r.err.find("Gruebler counts 6 x 3 - 17 = 1") != std::string::npos);
}

}  // namespace
