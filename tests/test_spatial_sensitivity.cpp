// Sensitivities and tolerances on spatial files (docs/format.md, Spatial mechanisms):
//  - the spatial slider-crank with its geometry as parameters: the slider's d(x)/dp against the
//    closed form x = sqrt(l^2 - (b - r sin th)^2 - (c + r cos th)^2), th = omega t, the crank
//    pin's and the crank's Euler parameters' against theirs, |p| = 1 kept to first order;
//  - a double wishbone with hardpoints as parameters: every d(C)/d(p) column, the suspension's
//    outputs included, against central differences of `analyze --param` runs;
//  - `tolerance`: the worst case against finite differences of the positions, and bounding a
//    Monte Carlo spread.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/tolerance.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "support/cli.hpp"
#include "support/csv_columns.hpp"
#include "support/files.hpp"

namespace {

namespace cg = kinegen::codegen;
using Columns = std::map<std::string, std::vector<double>>;

std::string mechanism(const std::string& name) {
  return std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/" + name + ".yaml";
}

using kinegen::test::kinegen_cli;

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  return text.replace(at, from.size(), to);
}

// The slider-crank of tests/mechanisms/spatial_slider_crank.yaml with its crank radius r, the
// bearing's y and z (b, c) and the rod's length l as parameters (the universal's point on the
// rod scaled with l), written to a scratch file.
std::string parametric_slider_crank() {
  std::string text = kinegen::test::read_text(mechanism("spatial_slider_crank"));
  text = replaced(text, "parameters: {omega: 6}",
                  "parameters: {omega: 6, r: 0.08, b: 0.1, c: 0.12, l: 0.3}");
  text = replaced(text, "si: [0, 0.1, 0.12], sj: [0, 0, 0]", "si: [0, b, c], sj: [0, 0, 0]");
  text = replaced(text, "si: [0, 0, 0.08], sj: [0, 0, 0]}", "si: [0, 0, r], sj: [0, 0, 0]}");
  text = replaced(text, "si: [0.2, -0.1, -0.2]", "si: [2*l/3, -l/3, -2*l/3]");
  text = replaced(text, "body: crank, s: [0, 0, 0.08]", "body: crank, s: [0, 0, r]");
  const auto dir = kinegen::test::scratch_dir("spatial_sensitivity", "slider_crank");
  kinegen::test::write_text(dir / "slider_crank.yaml", text);
  return (dir / "slider_crank.yaml").string();
}

std::string number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

TEST_CASE("spatial sensitivity: the slider-crank against its closed form", "[spatial]") {
  const double omega = 6, r = 0.08, b = 0.1, c = 0.12, l = 0.3;
  const auto run = kinegen_cli({"analyze", parametric_slider_crank(), "--t0", "0", "--t1", "1.3",
                                "--steps", "40", "--sensitivity", "omega,r,b,c,l"});
  INFO(run.err);
  REQUIRE(run.exit_code == 0);
  auto col = kinegen::test::csv_columns(run.out);
  const auto& t = col["t"];
  REQUIRE(t.size() == 41);
  double worst = 0, worst_unit = 0;
  const auto compare = [&](const std::string& column, std::size_t k, double truth) {
    REQUIRE(col.count(column) == 1);
    INFO(column << " at t = " << t[k] << ": " << col[column][k] << " against " << truth);
    CHECK(std::abs(col[column][k] - truth) <= 1e-9);
    worst = std::max(worst, std::abs(col[column][k] - truth));
  };
  for (std::size_t k = 0; k < t.size(); ++k) {
    const double th = omega * t[k], sn = std::sin(th), cs = std::cos(th);
    const double y = b - r * sn, z = c + r * cs;
    const double x = std::sqrt(l * l - y * y - z * z);
    const double dx_dth = r * (y * cs + z * sn) / x;
    const std::map<std::string, double> dx = {{"omega", dx_dth * t[k]},
                                              {"r", (y * sn - z * cs) / x},
                                              {"b", -y / x},
                                              {"c", -z / x},
                                              {"l", l / x}};
    for (const auto& [p, d] : dx) {
      const std::string of = ")/d(" + p + ")";
      compare("d(slider.x" + of, k, d);
      compare("d(S.x" + of, k, d);
      compare("d(slider_x" + of, k, d);  // an output
      compare("d(slider.y" + of, k, 0);
      compare("d(slider.z" + of, k, 0);
    }
    // The crank pin (0, b - r sin th, c + r cos th) and the crank's p = [cos th/2, sin th/2, 0,
    // 0]; the axle vector [0, -sin th, cos th].
    compare("d(P.y)/d(omega)", k, -r * cs * t[k]);
    compare("d(P.z)/d(omega)", k, -r * sn * t[k]);
    compare("d(P.y)/d(r)", k, -sn);
    compare("d(P.z)/d(r)", k, cs);
    compare("d(P.y)/d(b)", k, 1);
    compare("d(P.z)/d(c)", k, 1);
    compare("d(pin_y)/d(b)", k, 1);
    compare("d(axle.y)/d(omega)", k, -cs * t[k]);
    compare("d(axle.z)/d(omega)", k, -sn * t[k]);
    compare("d(axle_z)/d(omega)", k, -sn * t[k]);
    compare("d(axle.y)/d(r)", k, 0);
    compare("d(crank.e0)/d(omega)", k, -0.5 * t[k] * std::sin(th / 2));
    compare("d(crank.e1)/d(omega)", k, 0.5 * t[k] * std::cos(th / 2));
    compare("d(crank.e0)/d(l)", k, 0);
    // |p| = 1 to first order: p . dp/dq = 0 for every body and parameter.
    for (const char* body : {"crank", "rod", "slider"})
      for (const char* p : {"omega", "r", "b", "c", "l"}) {
        double dot = 0;
        for (const char* e : {"e0", "e1", "e2", "e3"})
          dot += col[std::string(body) + "." + e][k] *
                 col["d(" + std::string(body) + "." + e + ")/d(" + p + ")"][k];
        worst_unit = std::max(worst_unit, std::abs(dot));
      }
  }
  CHECK(worst_unit < 1e-12);
  WARN("slider-crank: largest difference from the closed form " << worst << ", |p . dp| "
                                                                << worst_unit);
}

// The double wishbone with hardpoints as parameters.
const std::vector<std::pair<std::string, double>> kHardpoints = {
    {"lbj_x", 0.005},          {"lbj_z", 0.13},  {"ubj_y", 0.67},
    {"tro_x", -0.13},          {"tro_z", 0.22},  {"pivot_z", 0.14},
    {"tie", 0.37027017163147}, {"radius", 0.30}, {"rack", 0.01}};

Columns wishbone(const std::vector<std::string>& extra) {
  std::vector<std::string> args = {
      "analyze", mechanism("spatial_wishbone_params"), "--t0", "0", "--t1", "1", "--steps", "8"};
  args.insert(args.end(), extra.begin(), extra.end());
  const auto r = kinegen_cli(args);
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  return kinegen::test::csv_columns(r.out);
}

TEST_CASE("spatial sensitivity: every column of a double wishbone against central differences",
          "[spatial]") {
  std::string names;
  for (const auto& [p, v] : kHardpoints) names += (names.empty() ? "" : ",") + p;
  Columns exact = wishbone({"--sensitivity", names});
  // Central differences with steps h and 2h: their difference, 3/4 of 2h's truncation error
  // (the h^2 term), bounds h's truncation error with margin; the position solve's rounding
  // (~1e-15 of the lengths, 0.3 to 0.8 m) divided by h adds ~1e-10.
  const double h = 1e-4;
  std::size_t compared = 0, toe_camber = 0;
  double worst = 0;
  for (const auto& [p, v] : kHardpoints) {
    std::map<int, Columns> at;
    for (int m : {-2, -1, 1, 2}) at[m] = wishbone({"--param", p + "=" + number(v + m * h)});
    const std::string of = ")/d(" + p + ")";
    for (const auto& [column, values] : exact) {
      if (column.rfind("d(", 0) != 0 || column.size() <= of.size() ||
          column.compare(column.size() - of.size(), of.size(), of) != 0)
        continue;
      const std::string c = column.substr(2, column.size() - 2 - of.size());
      REQUIRE(at[1].count(c) == 1);
      for (std::size_t k = 0; k < values.size(); ++k) {
        const double d1 = (at[1][c][k] - at[-1][c][k]) / (2 * h);
        const double d2 = (at[2][c][k] - at[-2][c][k]) / (4 * h);
        const double bound = std::abs(d2 - d1) + 1e-9;
        INFO(column << " at t = " << exact["t"][k] << ": " << values[k] << ", differences " << d1
                    << " (h) and " << d2 << " (2h)");
        CHECK(std::abs(values[k] - d1) <= bound);
        worst = std::max(worst, std::abs(values[k] - d1));
        ++compared;
        if (c == "toe" || c == "camber") toe_camber += std::abs(values[k]) > 1e-3;
      }
    }
  }
  // 9 parameters x (28 coordinates + 12 point + 3 vector + 12 output columns) x 9 rows.
  CHECK(compared == 9 * (28 + 12 + 3 + 12) * 9);
  CHECK(toe_camber > 50);  // toe and camber move with the hardpoints
  WARN("double wishbone: largest difference from central differences " << worst << " over "
                                                                       << compared);
}

TEST_CASE("spatial sensitivity: the motion ratios stay before the sensitivity columns",
          "[spatial]") {
  const auto r = kinegen_cli({"analyze", mechanism("spatial_wishbone_params"), "--t0", "0", "--t1",
                              "1", "--steps", "2", "--sensitivity", "tie"});
  REQUIRE(r.exit_code == 0);
  const std::string header = r.out.substr(0, r.out.find('\n'));
  const auto ratio = header.find(",spring.motion_ratio,");
  const auto first = header.find(",d(");
  REQUIRE(ratio != std::string::npos);
  REQUIRE(first != std::string::npos);
  CHECK(ratio < first);
  CHECK(header.substr(first + 1, header.find(',', first + 1) - first - 1) ==
        "d(lower_arm.x)/d(tie)");
}

cg::BuildOptions spatial_build() {
  cg::BuildOptions o;
  o.spatial = true;
  return o;
}

TEST_CASE("spatial tolerance: the worst case against finite differences", "[spatial]") {
  const std::string file = mechanism("spatial_wishbone_params");
  const auto model = cg::CompiledModel::from_file(file, {}, spatial_build());
  cg::ToleranceOptions options;
  options.tolerances = cg::parse_tolerances({"lbj_x=1e-4", "tro_x=2e-4", "ubj_y=1e-4"});
  options.grid = {0, 1, 4};
  const auto r = cg::tolerance_analysis(*model, options);
  // The truth: sum over the parameters of |C(p + d) - C(p - d)| / 2, each pair of positions
  // from `analyze --param` runs with the parameter moved (O(d^3) from the linear figure).
  std::vector<std::vector<double>> truth(r.t.size(), std::vector<double>(r.quantities.size()));
  for (const auto& tol : options.tolerances) {
    std::vector<std::vector<double>> side[2];
    for (int s : {0, 1}) {
      const double v =
          model->params()[model->symbols().find_param(tol.name)] + (s ? tol.delta : -tol.delta);
      const auto positions = kinegen::test::csv_columns(
          kinegen_cli({"analyze", file, "--t0", "0", "--t1", "1", "--steps", "4", "--param",
                       tol.name + "=" + number(v)})
              .out);
      for (std::size_t k = 0; k < r.t.size(); ++k) {
        side[s].emplace_back();
        for (const auto& q : r.quantities) {
          REQUIRE(positions.count(q) == 1);
          side[s].back().push_back(positions.at(q)[k]);
        }
      }
    }
    for (std::size_t k = 0; k < r.t.size(); ++k)
      for (std::size_t q = 0; q < r.quantities.size(); ++q)
        truth[k][q] += std::abs(side[1][k][q] - side[0][k][q]) / 2;
  }
  REQUIRE(r.quantities.size() == 28 + 12 + 3);
  for (std::size_t k = 0; k < r.t.size(); ++k)
    for (std::size_t q = 0; q < r.quantities.size(); ++q) {
      INFO(r.quantities[q] << " at t = " << r.t[k] << ": worst " << r.worst[k][q]
                           << ", differences " << truth[k][q]);
      // delta^2 of the second derivatives (~1e-8 of lengths ~1) against the sum.
      CHECK(std::abs(r.worst[k][q] - truth[k][q]) <= 1e-3 * truth[k][q] + 1e-9);
    }
}

TEST_CASE("spatial tolerance: the worst case bounds a Monte Carlo spread", "[spatial]") {
  const auto model =
      cg::CompiledModel::from_file(mechanism("spatial_wishbone_params"), {}, spatial_build());
  cg::ToleranceOptions options;
  options.tolerances = cg::parse_tolerances({"lbj_z=1e-4", "tro_z=2e-4", "radius=1e-3"});
  options.grid = {0, 1, 4};
  options.monte_carlo = 20;  // the bound holds for any number of samples
  options.seed = 3;
  const auto r = cg::tolerance_analysis(*model, options);
  REQUIRE(r.samples == 20);
  int moved = 0;
  for (std::size_t k = 0; k < r.t.size(); ++k)
    for (std::size_t q = 0; q < r.quantities.size(); ++q) {
      INFO(r.quantities[q] << " at t = " << r.t[k] << ": worst " << r.worst[k][q] << ", mc spread "
                           << r.mc_spread[k][q]);
      CHECK(r.mc_spread[k][q] <= 1.01 * r.worst[k][q] + 1e-13);
      moved += r.mc_spread[k][q] > 1e-6;
    }
  CHECK(moved > 50);
  // From the command line too: the summary lists a point's z.
  const auto cli = kinegen_cli({"tolerance", mechanism("spatial_wishbone_params"), "--tol",
                                "lbj_z=1e-4", "--t0", "0", "--t1", "1", "--steps", "2"});
  INFO(cli.err);
  CHECK(cli.exit_code == 0);
  CHECK(cli.out.find("\nLBJ.z ") != std::string::npos);
}

TEST_CASE("spatial sensitivity: a parameter of what the q0 pose fixes is refused", "[spatial]") {
  // The crank's rot0 angle sets where the revolute_angle's theta is 0, a number taken at the
  // q0 pose: d/d(a0) would miss it.
  std::string text = kinegen::test::read_text(mechanism("spatial_slider_crank"));
  text = replaced(text, "parameters: {omega: 6}", "parameters: {omega: 6, a0: 0}");
  text = replaced(text, "rot0: {axis: [1, 0, 0], angle: 0}", "rot0: {axis: [1, 0, 0], angle: a0}");
  const auto dir = kinegen::test::scratch_dir("spatial_sensitivity", "q0_pose");
  kinegen::test::write_text(dir / "m.yaml", text);
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"analyze", (dir / "m.yaml").string(), "--t0", "0", "--t1", "1",
                                 "--steps", "2", "--sensitivity", "omega,a0"},
        std::vector<std::string>{"tolerance", (dir / "m.yaml").string(), "--tol", "a0=0.01", "--t0",
                                 "0", "--t1", "1", "--steps", "2"}}) {
    const auto r = kinegen_cli(args);
    INFO(args[0] << ": " << r.err);
    CHECK(r.exit_code == 2);
    CHECK(r.out.empty());
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(r.err.find("revolute_angle") != std::string::npos);
    CHECK(r.err.find("'a0'") != std::string::npos);
  }
  // omega alone is computed.
  CHECK(kinegen_cli({"analyze", (dir / "m.yaml").string(), "--t0", "0", "--t1", "1", "--steps", "2",
                     "--sensitivity", "omega"})
            .exit_code == 0);
}

}  // namespace
