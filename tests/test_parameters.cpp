// Derived parameters and definitions against independent truths: a four-bar whose
// links are derived from a scale parameter follows the closed form of the scaled
// linkage, an override of the scale moves every derived length, an override of a
// derived one drops its formula, the sensitivities see through the formulas (central
// differences of the analysis), generated headers keep only the base parameters, and the
// errors name the item and its line.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "support/closed_form.hpp"
#include "support/run_command.hpp"

namespace kc = kinegen::codegen;

namespace {

// examples/four_bar.yaml with every length derived from one scale `u` (u = 1 is the example),
// c derived from derived parameters, and the crank's driver unchanged.
const std::string kScaled = R"y(name: scaled_four_bar
parameters:
  u: 1.0
  a: "u"
  b: "3.5*u"
  c: "b - a"
  d: "3*u"
  px: "1.5*u"
  py: "u"
  omega: 1.0
bodies:
  - {name: crank, q0: [0, 0, 0]}
  - {name: coupler, q0: ["a", 0, 0.78]}
  - {name: rocker, q0: ["d", 0, 1.37]}
joints:
  - {type: revolute, i: ground, j: crank}
  - {type: revolute, i: crank, j: coupler, si: ["a", 0]}
  - {type: revolute, i: coupler, j: rocker, si: ["b", 0], sj: ["c", 0]}
  - {type: revolute, i: ground, j: rocker, si: ["d", 0]}
drivers:
  - {type: absolute_angle, body: crank, f: "omega*t"}
points:
  - {name: P, body: coupler, s: ["px", "py"]}
)y";

std::unique_ptr<kc::CompiledModel> compile(const std::string& yaml,
                                           const std::vector<kc::ParamOverride>& o = {}) {
  return kc::CompiledModel::from_mechanism(kc::parse_mechanism(yaml, "test.yaml"), o);
}

std::vector<kc::StateRow> analyze(const kc::CompiledModel& m, const kc::TimeGrid& g,
                                  const kc::SensitivityModel* s = nullptr) {
  std::vector<kc::StateRow> rows;
  kc::AnalysisOptions o;
  o.sensitivity = s;
  kc::run_analysis(m, g, [&](const kc::StateRow& r) { rows.push_back(r); }, o);
  return rows;
}

std::string load_error(const std::string& yaml, const std::vector<kc::ParamOverride>& o = {}) {
  try {
    compile(yaml, o);
  } catch (const kc::InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("derived parameters: the scaled four-bar follows the scaled closed form", "[params]") {
  const kc::TimeGrid grid{0, 6.283185307179586, 24};
  for (const double u : {1.0, 2.0, 0.25}) {
    // c = b - a = 2.5 u: derived from derived parameters.
    const auto model = compile(kScaled, {{"u", std::to_string(u)}});
    CHECK(model->symbols().num_params() == 2);  // u and omega
    CHECK(model->symbols().derived_params().size() == 6);
    kinegen::closed_form::FourBarParams p;
    p.a = u;
    p.b = 3.5 * u;
    p.c = 2.5 * u;
    p.d = 3 * u;
    p.px = 1.5 * u;
    p.py = u;
    for (const auto& row : analyze(*model, grid)) {
      const auto exact = kinegen::closed_form::four_bar_state(row.t, p);
      for (int k = 0; k < 9; ++k) {
        INFO("u = " << u << ", t = " << row.t << ", q[" << k << "]");
        CHECK(row.q[k] == Approx(exact.q[k]).margin(1e-12 * std::max(1.0, u)));
        CHECK(row.qd[k] == Approx(exact.qd[k]).margin(1e-11 * std::max(1.0, u)));
      }
    }
  }
  // The parameter table lists every parameter in file order with its value.
  const auto model = compile(kScaled, {{"u", "2"}});
  const auto table = model->parameter_table();
  REQUIRE(table.size() == 8);
  CHECK(table[2].first == "b");
  CHECK(table[2].second == 7.0);
  CHECK(table[3].first == "c");
  CHECK(table[3].second == 5.0);
}

TEST_CASE("derived parameters: overriding one drops its formula", "[params]") {
  // d overridden: a base parameter now, u still scales the rest.
  const auto model = compile(kScaled, {{"d", "3.2"}});
  CHECK(model->symbols().find_param("d") >= 0);
  CHECK(model->symbols().find_derived("d") == nullptr);
  kinegen::closed_form::FourBarParams p;
  p.d = 3.2;
  for (const auto& row : analyze(*model, {0, 1, 4})) {
    const auto exact = kinegen::closed_form::four_bar_state(row.t, p);
    for (int k = 0; k < 9; ++k) CHECK(row.q[k] == Approx(exact.q[k]).margin(1e-12));
  }
}

TEST_CASE("derived parameters: sensitivities see through the formulas", "[params][sensitivity]") {
  const kc::TimeGrid grid{0, 1, 4};
  const double h = 1e-6;
  for (const std::string name : {"u", "b"}) {
    // u: every derived length moves with it; b (derived): treated as overridden.
    const auto model = compile(kScaled);
    auto base = model->with_base_parameters({name});
    CHECK((name == "b") == static_cast<bool>(base));
    const kc::CompiledModel& m = base ? *base : *model;
    const auto sens = kc::build_sensitivity(m, {name});
    const auto rows = analyze(m, grid, &sens);
    const double value = name == "u" ? 1.0 : 3.5;
    const auto plus = analyze(*compile(kScaled, {{name, std::to_string(value + h)}}), grid);
    const auto minus = analyze(*compile(kScaled, {{name, std::to_string(value - h)}}), grid);
    for (std::size_t r = 0; r < rows.size(); ++r)
      for (int k = 0; k < 9; ++k) {
        INFO(name << ", row " << r << ", q[" << k << "]");
        const double fd = (plus[r].q[k] - minus[r].q[k]) / (2 * h);
        CHECK(rows[r].dq_dp(k, 0) == Approx(fd).margin(1e-7));
      }
  }
}

TEST_CASE("derived parameters are not members of a generated header's Params", "[params]") {
  const auto model = compile(kScaled);
  const std::string header = kc::emit_header(*model);
  const auto params = header.substr(header.find("struct Params {"),
                                    header.find("};", header.find("struct Params {")) -
                                        header.find("struct Params {"));
  CHECK(params.find("double u = 1.0;") != std::string::npos);
  CHECK(params.find("double omega = 1.0;") != std::string::npos);
  CHECK(params.find("double b") == std::string::npos);
  // The derived lengths are computed from p.u where they are used.
  CHECK(header.find("T(p.u)") != std::string::npos);
}

TEST_CASE("definitions: named subexpressions in every later expression", "[params]") {
  // The slider-crank's rod constraint written with definitions: the crank tip A and the
  // distance to the slider, in an expression joint.
  const std::string yaml = R"y(name: defined
parameters: {r: 1.0, l: 2.5}
definitions:
  ax: "r*cos(phi_crank)"
  ay: "r*sin(phi_crank)"
  gap2: "(x_slider - ax)^2 + ay^2"
bodies:
  - {name: crank, q0: [0, 0, 0]}
  - {name: slider, q0: [3.5, 0, 0]}
joints:
  - {type: revolute, i: ground, j: crank}
  - {type: expression, equations: ["gap2 - l^2"]}
  - {type: absolute_y, body: slider, value: 0}
  - {type: absolute_angle, body: slider, value: 0}
drivers:
  - {type: absolute_angle, body: crank, f: "t"}
)y";
  const auto model = compile(yaml);
  for (const auto& row : analyze(*model, {0, 6.283185307179586, 36})) {
    const double th = row.t, r = 1, l = 2.5;
    const double x = r * std::cos(th) + std::sqrt(l * l - r * r * std::sin(th) * std::sin(th));
    CHECK(row.q[3] == Approx(x).margin(1e-12));
  }
  // A driver's f may not reach a coordinate through a definition.
  std::string bad = yaml;
  bad.replace(bad.find("f: \"t\""), 6, "f: \"t + ax\"");
  const std::string e = load_error(bad);
  CHECK_THAT(e, Catch::Contains("drivers[0]") && Catch::Contains("phi_crank"));
}

TEST_CASE("derived parameters and definitions: errors name the item and its line", "[params]") {
  const auto error_of = [](const std::string& yaml) { return load_error(yaml); };
  const std::string tail = R"y(bodies:
  - {name: crank, q0: [0, 0, 0]}
joints:
  - {type: revolute, i: ground, j: crank}
drivers:
  - {type: absolute_angle, body: crank, f: "t"}
)y";
  // A later parameter is not known yet.
  auto e = error_of("name: m\nparameters:\n  a: \"2*b\"\n  b: 1\n" + tail);
  CHECK_THAT(e, Catch::Contains("parameters.a") && Catch::Contains(":3:"));
  // Coordinates are not parameters' business.
  e = error_of("name: m\nparameters:\n  a: \"2*x_crank\"\n" + tail);
  CHECK_THAT(e, Catch::Contains("parameters.a") && Catch::Contains("x_crank"));
  // A derived value that is not a finite real number with the base values.
  e = error_of("name: m\nparameters:\n  a: 1\n  b: \"sqrt(a - 10)\"\n" + tail);
  CHECK_THAT(e, Catch::Contains("parameters.b") && Catch::Contains(":4:") &&
                    Catch::Contains("not a finite real number"));
  e = error_of("name: m\nparameters:\n  a: 0\n  b: \"1/a\"\n" + tail);
  CHECK_THAT(e, Catch::Contains("parameters.b"));
  // Definitions: duplicates, clashes, and a name used before it is defined.
  e = error_of("name: m\nparameters: {a: 1}\ndefinitions:\n  a: \"1\"\n" + tail);
  CHECK_THAT(e, Catch::Contains("definitions.a") && Catch::Contains("clashes"));
  e = error_of("name: m\ndefinitions:\n  g: \"2*h\"\n  h: \"1\"\n" + tail);
  CHECK_THAT(e, Catch::Contains("definitions.g") && Catch::Contains(":3:"));
  e = error_of("name: m\ndefinitions:\n  g: \"phi_crank_dot\"\n" + tail);
  CHECK_THAT(e, Catch::Contains("definitions.g"));
}
