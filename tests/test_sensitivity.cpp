// Parameter sensitivities (analyze --sensitivity) against independent truths:
//  1. a slider-crank's closed forms for d(slider.x)/d(l) and d(slider.x)/d(r);
//  2. the complex step of the whole position solve (Newton in complex arithmetic with the
//     parameter perturbed by i h) on every example and test mechanism;
//  3. central differences of the 40-digit reference analysis on every example.
// Bound: |got - truth| <= kBound * max(1, largest |truth| of the column's block), with lengths
// measured in the mechanism's length scale. dq/dp comes from one solve with the same Phi_q
// as the velocities, so its error is of the order of the velocities' (kappa * a few eps,
// docs/accuracy.md: kappa <= ~1e3 on these mechanisms); 1e-10 leaves room for that.
#include <Eigen/Dense>
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <filesystem>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "support/run_command.hpp"

namespace {

namespace cg = kinegen::codegen;
namespace fs = std::filesystem;
using Complex = std::complex<double>;

constexpr double kBound = 1e-10;

std::vector<std::string> yaml_files(const fs::path& dir) {
  std::vector<std::string> f;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".yaml") f.push_back(e.path().string());
  std::sort(f.begin(), f.end());
  return f;
}

std::vector<std::string> example_files() {
  return yaml_files(fs::path(KINEGEN_SOURCE_DIR) / "examples");
}

// Every planar mechanism that analyzes over t in [0, 1]: the examples and the test mechanisms
// except all_types.yaml (a loader test that is singular by design) and the spatial ones
// (test_spatial_sensitivity.cpp).
std::vector<std::string> analyzable_files() {
  auto files = example_files();
  for (const auto& f : yaml_files(fs::path(KINEGEN_SOURCE_DIR) / "tests" / "mechanisms")) {
    const std::string name = fs::path(f).filename().string();
    if (name != "all_types.yaml" && name.rfind("spatial_", 0) != 0) files.push_back(f);
  }
  return files;
}

// The base parameters (a derived one follows them; the sensitivities to these cover it).
std::vector<std::string> all_parameters(const cg::CompiledModel& model) {
  std::vector<std::string> names;
  for (int k = 0; k < model.symbols().num_params(); ++k)
    names.push_back(model.symbols().param_name(k));
  return names;
}

std::vector<cg::StateRow> analyze(const cg::CompiledModel& model, const cg::TimeGrid& grid,
                                  const cg::SensitivityModel* sensitivity) {
  std::vector<cg::StateRow> rows;
  cg::AnalysisOptions options;
  options.sensitivity = sensitivity;
  cg::run_analysis(
      model, grid, [&](const cg::StateRow& r) { rows.push_back(r); }, options);
  return rows;
}

// The positions one row reports, in the CSV's order: q, then the points' x, y.
std::vector<double> scales(const cg::CompiledModel& model) {
  std::vector<double> s;
  const double length = model.symbolic().length_scale;
  for (int k = 0; k < model.nq(); ++k) s.push_back(k % 3 == 2 ? 1.0 : length);
  for (std::size_t p = 0; p < model.mechanism().points.size(); ++p) s.insert(s.end(), 2, length);
  return s;
}

// Compares one parameter's column (dq/dp then the points') with the truth.
void require_close(const cg::CompiledModel& model, const cg::StateRow& row, int k,
                   const std::vector<double>& truth, const std::string& what) {
  std::vector<double> got;
  for (int i = 0; i < model.nq(); ++i) got.push_back(row.dq_dp(i, k));
  for (int i = 0; i < row.dpoints_dp.rows(); ++i) got.push_back(row.dpoints_dp(i, k));
  REQUIRE(got.size() == truth.size());
  const auto s = scales(model);
  double size = 1;
  for (std::size_t i = 0; i < got.size(); ++i) size = std::max(size, std::abs(truth[i]) / s[i]);
  for (std::size_t i = 0; i < got.size(); ++i) {
    INFO(what << " t = " << row.t << " column " << i << ": got " << got[i] << ", truth "
              << truth[i]);
    REQUIRE(std::abs(got[i] - truth[i]) / s[i] <= kBound * size);
  }
}

}  // namespace

TEST_CASE("sensitivities of a slider-crank match the closed forms", "[sensitivity]") {
  // Crank of length r at the origin, rod of length l, slider on the x axis:
  // x = r cos th + sqrt(l^2 - r^2 sin^2 th).
  const std::string yaml = R"(
name: sc
parameters: {r: 0.8, l: 2.1, omega: 1.0}
bodies:
  - {name: crank, q0: [0, 0, 0]}
  - {name: rod, q0: [2.9, 0, 0]}
joints:
  - {type: revolute, i: ground, j: crank, si: [0, 0], sj: [0, 0]}
  - {type: revolute, i: crank, j: rod, si: ["r", 0], sj: [0, 0]}
  - {type: absolute_y, body: rod, s: ["l", 0], value: 0}
drivers:
  - {type: absolute_angle, body: crank, f: "omega*t"}
points:
  - {name: slider, body: rod, s: ["l", 0]}
)";
  const auto model = cg::CompiledModel::from_mechanism(cg::parse_mechanism(yaml, "sc.yaml"));
  const auto sens = cg::build_sensitivity(*model, {"l", "r", "omega"});
  const double r = 0.8, l = 2.1;
  const auto rows = analyze(*model, {0, 2 * std::acos(-1.0), 72}, &sens);
  REQUIRE(rows.size() == 73);
  for (const auto& row : rows) {
    const double th = row.t, s = std::sin(th);
    const double root = std::sqrt(l * l - r * r * s * s);
    INFO("t = " << th);
    REQUIRE(std::abs(row.points[0].r.x() - (r * std::cos(th) + root)) <= 1e-13);
    // Column order: l, r, omega; points' rows are x, y.
    CHECK(std::abs(row.dpoints_dp(0, 0) - l / root) <= kBound);
    CHECK(std::abs(row.dpoints_dp(0, 1) - (std::cos(th) - r * s * s / root)) <= kBound);
    // omega moves the crank angle by t: d x / d omega = t dx/dth.
    const double dx_dth = -r * s - r * r * s * std::cos(th) / root;
    CHECK(std::abs(row.dpoints_dp(0, 2) - th * dx_dth) <= kBound * std::max(1.0, th));
    CHECK(std::abs(row.dpoints_dp(1, 0)) <= kBound);  // the slider stays on its line
    CHECK(std::abs(row.dq_dp(2, 2) - th) <= kBound * std::max(1.0, th));  // d(crank.phi)/d(omega)
  }
}

TEST_CASE("sensitivities equal the complex step of the whole position solve", "[sensitivity]") {
  // q(p + i h) by Newton in complex arithmetic from the real solution; Im q / h = dq/dp with
  // no cancellation (h = 1e-30: the O(h^2) term is far below rounding).
  const double h = 1e-30;
  int checked = 0;
  for (const auto& file : analyzable_files()) {
    const auto model = cg::CompiledModel::from_file(file);
    // Outputs that read velocities have no sensitivities: refused (test_outputs.cpp).
    const auto& velocity = model->symbolic().output_reads_velocity;
    if (std::find(velocity.begin(), velocity.end(), true) != velocity.end()) continue;
    const auto names = all_parameters(*model);
    const auto sens = cg::build_sensitivity(*model, names);
    const auto rows = analyze(*model, {0, 1, 10}, &sens);
    const auto& prog = model->programs();
    // Points' offsets as a program in the parameters, evaluated in complex too.
    std::vector<GiNaC::ex> offsets;
    for (const auto& [x, y] : model->symbolic().point_s) {
      offsets.push_back(x);
      offsets.push_back(y);
    }
    const cg::Program offset_program = cg::lower(offsets, model->symbols());
    cg::ProgramEvaluator<Complex> phi(prog.phi), phi_q(prog.phi_q), offset(offset_program);
    const int nq = model->nq(), nc = model->nc();
    for (const auto& row : rows) {
      for (std::size_t k = 0; k < names.size(); ++k) {
        std::vector<Complex> params(model->params().begin(), model->params().end());
        params[sens.params[k]] += Complex(0, h);
        Eigen::VectorXcd q = row.q.cast<Complex>(), res(nc);
        std::vector<Complex> values(prog.jac_rows.size());
        for (int it = 0; it < 6; ++it) {
          phi.run(q.data(), nullptr, row.t, params.data(), res.data());
          phi_q.run(q.data(), nullptr, row.t, params.data(), values.data());
          Eigen::MatrixXcd jac = Eigen::MatrixXcd::Zero(nc, nq);
          for (std::size_t e = 0; e < values.size(); ++e)
            jac(prog.jac_rows[e], prog.jac_cols[e]) = values[e];
          q -= jac.colPivHouseholderQr().solve(res);  // least squares where redundant
        }
        std::vector<double> truth;
        for (int i = 0; i < nq; ++i) truth.push_back(q[i].imag() / h);
        std::vector<Complex> s(offsets.size());
        offset.run(q.data(), nullptr, row.t, params.data(), s.data());
        const auto& points = model->mechanism().points;
        for (std::size_t p = 0; p < points.size(); ++p) {
          const int b = 3 * points[p].body;
          const Complex c = std::cos(q[b + 2]), sn = std::sin(q[b + 2]);
          truth.push_back((q[b] + c * s[2 * p] - sn * s[2 * p + 1]).imag() / h);
          truth.push_back((q[b + 1] + sn * s[2 * p] + c * s[2 * p + 1]).imag() / h);
        }
        require_close(*model, row, static_cast<int>(k), truth, file + " d/d(" + names[k] + ")");
        ++checked;
      }
    }
  }
  CHECK(checked > 100);
}

TEST_CASE("sensitivities equal central differences of the 40-digit reference", "[sensitivity]") {
  // (q(p + h) - q(p - h)) / 2h in 40-digit arithmetic: truncation ~ h^2 = 1e-20, rounding
  // ~ 1e-35 / h = 1e-23, both far below the bound.
  const std::string h = "1e-10";
  const int digits = 40;
  const cg::TimeGrid grid{0, 1, 4};
  for (const auto& file : example_files()) {
    const auto model = cg::CompiledModel::from_file(file);
    const auto names = all_parameters(*model);
    const auto sens = cg::build_sensitivity(*model, names);
    const auto rows = analyze(*model, grid, &sens);
    for (std::size_t k = 0; k < names.size(); ++k) {
      const auto& text =
          model->mechanism().parameters[model->symbols().param_source(static_cast<int>(k))]
              .value.text;
      std::vector<std::vector<cg::ReferenceRow>> side(2);
      for (int sgn = 0; sgn < 2; ++sgn) {
        const auto moved = cg::CompiledModel::from_file(
            file, {{names[k], "(" + text + ")" + (sgn ? "-" : "+") + h}});
        cg::run_reference_analysis_exact(
            *moved, grid, digits, [&](const cg::ReferenceRow& r) { side[sgn].push_back(r); });
      }
      REQUIRE(side[0].size() == rows.size());
      const GiNaC::numeric two_h = GiNaC::numeric(2) / GiNaC::numeric(10000000000);
      for (std::size_t r = 0; r < rows.size(); ++r) {
        std::vector<double> truth;
        for (int i = 0; i < model->nq(); ++i)
          truth.push_back(((side[0][r].q[i] - side[1][r].q[i]) / two_h).to_double());
        for (std::size_t p = 0; p < side[0][r].points.size(); ++p)
          for (int c = 0; c < 2; ++c)
            truth.push_back(
                ((side[0][r].points[p][c] - side[1][r].points[p][c]) / two_h).to_double());
        require_close(*model, rows[r], static_cast<int>(k), truth, file + " d/d(" + names[k] + ")");
      }
    }
  }
}

TEST_CASE("the sparse path gives the dense path's sensitivities", "[sensitivity]") {
  // Large models take the sparse LU (sparse_above_nq); sending the four-bar there checks that
  // its factorization is reused the same way. Both solve the same system: agreement to 1e-12.
  const auto model =
      cg::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/examples/four_bar.yaml");
  const auto sens = cg::build_sensitivity(*model, all_parameters(*model));
  std::vector<cg::StateRow> dense, sparse;
  cg::AnalysisOptions options;
  options.block_solver = false;  // the dense and the sparse path
  options.sensitivity = &sens;
  cg::run_analysis(
      *model, {0, 6, 24}, [&](const cg::StateRow& r) { dense.push_back(r); }, options);
  options.sparse_above_nq = 0;
  cg::run_analysis(
      *model, {0, 6, 24}, [&](const cg::StateRow& r) { sparse.push_back(r); }, options);
  REQUIRE(dense.size() == sparse.size());
  for (std::size_t k = 0; k < dense.size(); ++k) {
    CHECK((dense[k].dq_dp - sparse[k].dq_dp).cwiseAbs().maxCoeff() <= 1e-12);
    CHECK((dense[k].dpoints_dp - sparse[k].dpoints_dp).cwiseAbs().maxCoeff() <= 1e-12);
    CHECK(dense[k].dq_dp.cwiseAbs().maxCoeff() > 0.1);
  }
}

TEST_CASE("analyze --sensitivity: columns, unknown names, unused parameters", "[sensitivity]") {
  const std::string exe = KINEGEN_EXE;
  const std::string mech = std::string(KINEGEN_SOURCE_DIR) + "/examples/slider_crank.yaml";
  SECTION("the columns follow all others, per parameter in the order given") {
    const auto model = cg::CompiledModel::from_file(mech);
    const auto columns = cg::sensitivity_columns(model->mechanism(), {"omega", "l"});
    REQUIRE(columns.size() == 2 * (6 + 4));
    CHECK(columns.front() == "d(crank.x)/d(omega)");
    CHECK(columns[5] == "d(rod.phi)/d(omega)");
    CHECK(columns[9] == "d(slider.y)/d(omega)");
    CHECK(columns[10] == "d(crank.x)/d(l)");
    const std::string header = cg::csv_header(model->mechanism(), {"omega", "l"});
    CHECK(header.find(",slider.ay,d(crank.x)/d(omega),") != std::string::npos);
  }
  SECTION("an unknown parameter is an error naming it (exit 2)") {
    const auto r = kinegen::test::run_command({exe, "analyze", mech, "--t0", "0", "--t1", "1",
                                               "--steps", "2", "--sensitivity", "l,nope"});
    CHECK(r.exit_code == 2);
    CHECK(r.err.rfind("error: ", 0) == 0);
    CHECK(r.err.find("no parameter 'nope'") != std::string::npos);
    CHECK(r.out.empty());
  }
  SECTION("a repeated name is an error") {
    const auto model = cg::CompiledModel::from_file(mech);
    CHECK_THROWS_WITH(cg::build_sensitivity(*model, {"l", "omega", "l"}),
                      Catch::Contains("'l' is given twice"));
  }
  SECTION("with --reference-digits it is refused") {
    const auto r =
        kinegen::test::run_command({exe, "analyze", mech, "--t0", "0", "--t1", "1", "--steps", "2",
                                    "--sensitivity", "l", "--reference-digits", "30"});
    CHECK(r.exit_code == 2);
  }
  SECTION("an empty name is an error") {
    const auto r = kinegen::test::run_command({exe, "analyze", mech, "--t0", "0", "--t1", "1",
                                               "--steps", "2", "--sensitivity", "l,,omega"});
    CHECK(r.exit_code == 2);
    CHECK(r.err.find("--sensitivity expects parameter names") != std::string::npos);
  }
  SECTION("a parameter nothing depends on gives zero columns") {
    const std::string yaml = R"(
name: unused
parameters: {spare: 3.0, omega: 1.0}
bodies:
  - {name: crank, q0: [0, 0, 0]}
joints:
  - {type: revolute, i: ground, j: crank, si: [0, 0], sj: [0, 0]}
drivers:
  - {type: absolute_angle, body: crank, f: "omega*t"}
points:
  - {name: tip, body: crank, s: [1, 0]}
)";
    const auto model = cg::CompiledModel::from_mechanism(cg::parse_mechanism(yaml, "unused.yaml"));
    const auto sens = cg::build_sensitivity(*model, {"spare"});
    const auto rows = analyze(*model, {0, 1, 3}, &sens);
    for (const auto& row : rows) {
      CHECK(row.dq_dp.isZero(0));
      CHECK(row.dpoints_dp.isZero(0));
      // The last five columns (crank x, y, phi; tip x, y) print as 0, not -0.
      const std::string line = cg::csv_row(row, 1);
      CHECK(line.substr(line.size() - 11) == ",0,0,0,0,0\n");
    }
  }
}
