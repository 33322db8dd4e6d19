// Outputs: values with exact first and second time derivatives, in the analysis
// rows (CSV), the 40-digit reference, `eval`'s JSON, sensitivities and the generated header's
// outputs function, against hand-derived closed forms of tests/support/closed_form.hpp and the
// complex step; and hostile outputs refused with one error line. Outputs that read velocities
// (as loads may): exact values and .v, .a nan, in analyze, the reference, eval, the generated
// header and simulate; refused where they cannot be exact (--sensitivity, stop_when's O.v).
//
// Mechanisms: tests/mechanisms/four_bar_outputs.yaml (transmission angle mu, cos mu, mu in
// degrees, |O2 B|), tests/mechanisms/slider_crank_outputs.yaml (stroke, a cylinder's length
// through definitions, an output with explicit t terms) and
// tests/mechanisms/slider_crank_velocity_outputs.yaml (the slider's speed, phid_rod*x_rod, a
// kinetic-energy-like sum with a t term, and the stroke beside them); and
// examples/dynamics/four_bar_damped.yaml with a damper's power and a free coordinate's rate.
#include <algorithm>
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "four_bar_outputs.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "slider_crank_outputs.hpp"
#include "slider_crank_velocity_outputs.hpp"
#include "support/closed_form.hpp"
#include "support/run_command.hpp"

namespace kc = kinegen::codegen;
namespace cf = kinegen::closed_form;
namespace fs = std::filesystem;
using Triple = std::array<double, 3>;

namespace {

const double kPi = std::acos(-1.0);
const std::string kFourBar =
    std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/four_bar_outputs.yaml";
const std::string kSliderCrank =
    std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/slider_crank_outputs.yaml";

// Value, velocity, acceleration of each four-bar output from the closed-form state, by the chain
// rule written out by hand: mu = phi3 - phi2; cos mu; mu * 180 / pi; |B| with
// B = O4 + c (cos phi3, sin phi3).
std::vector<Triple> four_bar_truth(double t, const cf::FourBarParams& p = {}) {
  const auto st = cf::four_bar_state(t, p);
  const double mu = st.q[8] - st.q[5], mv = st.qd[8] - st.qd[5], ma = st.qdd[8] - st.qdd[5];
  const double p3 = st.q[8], w3 = st.qd[8], a3 = st.qdd[8];
  const double bx = p.d + p.c * std::cos(p3), by = p.c * std::sin(p3);
  const double bvx = -p.c * w3 * std::sin(p3), bvy = p.c * w3 * std::cos(p3);
  const double bax = -p.c * a3 * std::sin(p3) - p.c * w3 * w3 * std::cos(p3);
  const double bay = p.c * a3 * std::cos(p3) - p.c * w3 * w3 * std::sin(p3);
  const double len = std::hypot(bx, by), lv = (bx * bvx + by * bvy) / len;
  const double la = (bvx * bvx + bvy * bvy + bx * bax + by * bay - lv * lv) / len;
  const double deg = 180 / kPi;
  return {{mu, mv, ma},
          {std::cos(mu), -std::sin(mu) * mv, -std::cos(mu) * mv * mv - std::sin(mu) * ma},
          {mu * deg, mv * deg, ma * deg},
          {len, lv, la}};
}

// The slider-crank's outputs: stroke x2 - (l - 1); the cylinder from (gx, gy) = (0.5, -1.5) to
// the crank tip (cos phi1, sin phi1); t x2 + sin(omega t).
std::vector<Triple> slider_crank_truth(double t) {
  const cf::SliderCrankParams p;
  const auto st = cf::slider_crank_state(t, p);
  const double w = p.omega, p1 = st.q[2];
  const double dx = std::cos(p1) - 0.5, dy = std::sin(p1) + 1.5;
  const double vx = -w * std::sin(p1), vy = w * std::cos(p1);
  const double ax = -w * w * std::cos(p1), ay = -w * w * std::sin(p1);
  const double len = std::hypot(dx, dy), lv = (dx * vx + dy * vy) / len;
  const double la = (vx * vx + vy * vy + dx * ax + dy * ay - lv * lv) / len;
  const double x2 = st.q[3], v2 = st.qd[3], a2 = st.qdd[3];
  return {{x2 - (p.l - 1), v2, a2},
          {len, lv, la},
          {t * x2 + std::sin(w * t), x2 + t * v2 + w * std::cos(w * t),
           2 * v2 + t * a2 - w * w * std::sin(w * t)}};
}

struct Worst {
  double value = 0, rate = 0, accel = 0;
  void add(const Triple& got, const Triple& want) {
    value = std::max(value, std::abs(got[0] - want[0]) / (1 + std::abs(want[0])));
    rate = std::max(rate, std::abs(got[1] - want[1]) / (1 + std::abs(want[1])));
    accel = std::max(accel, std::abs(got[2] - want[2]) / (1 + std::abs(want[2])));
  }
};

const kc::TimeGrid kTurn{0.0, 2 * std::acos(-1.0), 90};

template <class Truth>
Worst compare_analysis(const kc::CompiledModel& model, const Truth& truth, bool reference) {
  Worst w;
  int rows = 0;
  const auto sink = [&](const kc::StateRow& row) {
    const auto want = truth(row.t);
    REQUIRE(row.outputs.size() == want.size());
    for (std::size_t o = 0; o < want.size(); ++o) w.add(row.outputs[o], want[o]);
    ++rows;
  };
  if (reference)
    kc::run_reference_analysis(model, kTurn, 40, sink);
  else
    kc::run_analysis(model, kTurn, sink);
  CHECK(rows == kTurn.steps + 1);
  return w;
}

kinegen::test::CommandResult run_kinegen(std::vector<std::string> args) {
  args.insert(args.begin(), KINEGEN_EXE);
  return kinegen::test::run_command(args);
}

std::vector<std::string> split(const std::string& line, char sep) {
  std::vector<std::string> items;
  std::stringstream in(line);
  for (std::string item; std::getline(in, item, sep);) items.push_back(item);
  return items;
}

}  // namespace

TEST_CASE("four-bar outputs (transmission angle, |O2 B|) match the closed form", "[outputs]") {
  const auto model = kc::CompiledModel::from_file(kFourBar);
  const Worst w = compare_analysis(
      *model, [](double t) { return four_bar_truth(t); }, false);
  std::printf(
      "four_bar outputs vs closed form (relative to 1 + |truth|): value %.2e, v %.2e, "
      "a %.2e\n",
      w.value, w.rate, w.accel);
  CHECK(w.value < 1e-13);
  CHECK(w.rate < 1e-12);
  CHECK(w.accel < 1e-11);
}

TEST_CASE("slider-crank outputs (stroke, cylinder via definitions, t terms) match the closed form",
          "[outputs]") {
  const auto model = kc::CompiledModel::from_file(kSliderCrank);
  const Worst w = compare_analysis(*model, slider_crank_truth, false);
  std::printf("slider_crank outputs vs closed form: value %.2e, v %.2e, a %.2e\n", w.value, w.rate,
              w.accel);
  CHECK(w.value < 1e-13);
  CHECK(w.rate < 1e-12);
  CHECK(w.accel < 1e-11);
}

TEST_CASE("the 40-digit reference gives the outputs to rounding", "[outputs]") {
  for (const std::string& file : {kFourBar, kSliderCrank}) {
    const auto model = kc::CompiledModel::from_file(file);
    const Worst w = file == kFourBar ? compare_analysis(
                                           *model, [](double t) { return four_bar_truth(t); }, true)
                                     : compare_analysis(*model, slider_crank_truth, true);
    std::printf("%s: reference outputs vs closed form: value %.2e, v %.2e, a %.2e\n",
                fs::path(file).stem().c_str(), w.value, w.rate, w.accel);
    // The closed forms' own double rounding (acos, atan2 and the chains above) is the limit:
    // the four-bar's w2, w3 come from quotients of sines (1.5e-14 measured, in mu_deg.v).
    CHECK(w.value < 1e-14);
    CHECK(w.rate < 5e-14);
    CHECK(w.accel < 1e-14);
  }
}

TEST_CASE("analyze puts NAME, NAME.v, NAME.a after the points, also with --reference-digits",
          "[outputs]") {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "outputs_cli";
  fs::create_directories(dir);
  const std::string csv = (dir / "plain.csv").string(), ref = (dir / "ref.csv").string();
  const std::vector<std::string> grid = {"--t0", "0", "--t1", "3", "--steps", "6"};
  auto args = std::vector<std::string>{"analyze", kSliderCrank, "-o", csv};
  args.insert(args.end(), grid.begin(), grid.end());
  REQUIRE(run_kinegen(args).exit_code == 0);
  args = {"analyze", kSliderCrank, "-o", ref, "--reference-digits", "40"};
  args.insert(args.end(), grid.begin(), grid.end());
  REQUIRE(run_kinegen(args).exit_code == 0);
  std::ifstream a(csv), b(ref);
  std::string ha, hb;
  std::getline(a, ha);
  std::getline(b, hb);
  CHECK(ha == hb);
  const std::string tail =
      "slider.ay,stroke,stroke.v,stroke.a,cylinder,cylinder.v,cylinder.a,timed,"
      "timed.v,timed.a";
  CHECK(ha.size() >= tail.size());
  CHECK(ha.compare(ha.size() - tail.size(), tail.size(), tail) == 0);
  const auto names = split(ha, ',');
  for (std::string la, lb; std::getline(a, la) && std::getline(b, lb);) {
    const auto va = split(la, ','), vb = split(lb, ',');
    REQUIRE(va.size() == names.size());
    REQUIRE(vb.size() == names.size());
    const double t = std::stod(va[0]);
    const auto truth = slider_crank_truth(t);
    for (std::size_t o = 0; o < truth.size(); ++o)
      for (int d = 0; d < 3; ++d) {
        const std::size_t col = names.size() - 9 + 3 * o + d;
        INFO(names[col] << " at t = " << t);
        const double x = std::stod(va[col]), y = std::stod(vb[col]);
        CHECK(std::abs(x - y) <= 1e-13 * (1 + std::abs(y)));
        CHECK(std::abs(y - truth[o][d]) <= 1e-14 * (1 + std::abs(truth[o][d])));
      }
  }
  // A file without outputs keeps its v1 columns: the last is still a point's.
  args = {"analyze", std::string(KINEGEN_SOURCE_DIR) + "/examples/slider_crank.yaml", "-o", csv};
  args.insert(args.end(), grid.begin(), grid.end());
  REQUIRE(run_kinegen(args).exit_code == 0);
  std::ifstream v1(csv);
  std::getline(v1, ha);
  CHECK(ha.substr(ha.rfind(',') + 1) == "slider.ay");
}

TEST_CASE("eval's JSON has the outputs' values", "[outputs]") {
  const double t = 0.7;
  const auto st = cf::four_bar_state(t);
  std::string q;
  for (double v : st.q) {
    char text[40];
    std::snprintf(text, sizeof text, "%.17g", v);
    q += (q.empty() ? "" : ",") + std::string(text);
  }
  const auto r = run_kinegen({"eval", kFourBar, "--t", "0.7", "--q", q});
  REQUIRE(r.exit_code == 0);
  const auto at = r.out.find("\"outputs\": [");
  REQUIRE(at != std::string::npos);
  const auto end = r.out.find(']', at);
  const auto values = split(r.out.substr(at + 12, end - at - 12), ',');
  const auto truth = four_bar_truth(t);
  REQUIRE(values.size() == truth.size());
  for (std::size_t o = 0; o < truth.size(); ++o)
    CHECK(std::abs(std::stod(values[o]) - truth[o][0]) <= 1e-14 * (1 + std::abs(truth[o][0])));
  // Without outputs the JSON is unchanged.
  const auto v1 =
      run_kinegen({"eval", std::string(KINEGEN_SOURCE_DIR) + "/examples/four_bar.yaml"});
  CHECK(v1.out.find("outputs") == std::string::npos);
}

// The slider-crank in closed form on any scalar type (the complex step needs complex t):
// q(t) and qd(t) of examples/slider_crank.yaml with l = 2, omega = 1.
template <class T>
void slider_crank_q(T t, T* q, T* qd) {
  using std::acos, std::cos, std::sin, std::sqrt;
  const double l = 2.0;
  const T s1 = sin(t), c1 = cos(t), cp2 = s1 / l, sp2 = sqrt(T(1) - cp2 * cp2);
  const T w2 = -c1 / (l * sp2);
  const T values[6] = {T(0), T(0), t, c1 + l * sp2, T(0), acos(cp2)};
  const T rates[6] = {T(0), T(0), T(1), -s1 + l * cp2 * w2, T(0), w2};
  for (int k = 0; k < 6; ++k) q[k] = values[k], qd[k] = rates[k];
}

TEST_CASE("the generated outputs function agrees with analyze and with the complex step",
          "[outputs]") {
  using Model = kinegen::models::slider_crank_outputs;
  static_assert(Model::num_outputs == 3);
  const auto model = kc::CompiledModel::from_file(kSliderCrank);
  const Model::Params p;
  double worst_analyze = 0, worst_v = 0, worst_a = 0;
  kc::run_analysis(*model, kTurn, [&](const kc::StateRow& row) {
    std::array<double, 3> value, velocity, acceleration;
    Model::outputs(row.q.data(), row.qd.data(), row.qdd.data(), row.t, p, value.data(),
                   velocity.data(), acceleration.data());
    for (int o = 0; o < 3; ++o) {
      const Triple got{value[o], velocity[o], acceleration[o]};
      for (int d = 0; d < 3; ++d)
        worst_analyze = std::max(worst_analyze, std::abs(got[d] - row.outputs[o][d]) /
                                                    (1 + std::abs(row.outputs[o][d])));
    }
    // Complex step along the exact motion: Im O(q(t + ih), t + ih) / h = dO/dt, and the same of
    // the generated rate O_q qd + O_t gives d2O/dt2 without the header's own O_q qdd path.
    using C = std::complex<double>;
    const double h = 1e-30;
    const C tc(row.t, h);
    C q[6], qd[6], out[Model::num_outputs * (2 + Model::nq)];
    slider_crank_q(tc, q, qd);
    C v[3];
    Model::output_values(q, tc, p, v);
    Model::output_rates(q, qd, tc, p, out);
    const auto truth = slider_crank_truth(row.t);
    for (int o = 0; o < 3; ++o) {
      worst_v = std::max(worst_v, std::abs(v[o].imag() / h - row.outputs[o][1]) /
                                      (1 + std::abs(row.outputs[o][1])));
      worst_a = std::max(worst_a, std::abs(out[o].imag() / h - row.outputs[o][2]) /
                                      (1 + std::abs(row.outputs[o][2])));
      CHECK(std::abs(out[o].imag() / h - truth[o][2]) <= 1e-13 * (1 + std::abs(truth[o][2])));
    }
  });
  std::printf("generated outputs vs analyze %.2e; analyze vs complex step: v %.2e, a %.2e\n",
              worst_analyze, worst_v, worst_a);
  CHECK(worst_analyze <= 1e-15);
  CHECK(worst_v < 1e-12);
  CHECK(worst_a < 1e-12);
  // The four-bar's header too, at one closed-form state.
  using FourBar = kinegen::models::four_bar_outputs;
  const auto st = cf::four_bar_state(1.3);
  std::array<double, 4> value, velocity, acceleration;
  FourBar::outputs(st.q.data(), st.qd.data(), st.qdd.data(), 1.3, FourBar::Params{}, value.data(),
                   velocity.data(), acceleration.data());
  const auto truth = four_bar_truth(1.3);
  for (int o = 0; o < 4; ++o) {
    CHECK(std::abs(value[o] - truth[o][0]) <= 1e-13 * (1 + std::abs(truth[o][0])));
    CHECK(std::abs(velocity[o] - truth[o][1]) <= 1e-13 * (1 + std::abs(truth[o][1])));
    CHECK(std::abs(acceleration[o] - truth[o][2]) <= 1e-12 * (1 + std::abs(truth[o][2])));
  }
}

TEST_CASE("sensitivities include the outputs: d(O)/d(p) against central differences", "[outputs]") {
  const auto model = kc::CompiledModel::from_file(kFourBar);
  const std::vector<std::string> names = {"c", "a"};
  const kc::SensitivityModel sens = kc::build_sensitivity(*model, names);
  const auto columns = kc::sensitivity_columns(model->mechanism(), names);
  CHECK(std::find(columns.begin(), columns.end(), "d(o2b)/d(c)") != columns.end());
  CHECK(columns.back() == "d(o2b)/d(a)");
  kc::AnalysisOptions options;
  options.sensitivity = &sens;
  double worst = 0;
  kc::run_analysis(
      *model, {0.0, 6.0, 12},
      [&](const kc::StateRow& row) {
        REQUIRE(row.doutputs_dp.rows() == 4);
        REQUIRE(row.doutputs_dp.cols() == 2);
        for (int k = 0; k < 2; ++k) {
          const double h = 1e-5;
          cf::FourBarParams up, down;
          (k == 0 ? up.c : up.a) += h;
          (k == 0 ? down.c : down.a) -= h;
          const auto fu = four_bar_truth(row.t, up), fd = four_bar_truth(row.t, down);
          for (int o = 0; o < 4; ++o) {
            const double want = (fu[o][0] - fd[o][0]) / (2 * h);
            worst = std::max(worst, std::abs(row.doutputs_dp(o, k) - want) / (1 + std::abs(want)));
          }
        }
      },
      options);
  std::printf("four_bar d(output)/d(c, a) vs central differences: %.2e\n", worst);
  CHECK(worst < 1e-8);  // the differences' truncation, h^2 ~ 1e-10, times the third derivative
}

TEST_CASE("hostile outputs: one error line with the YAML line, exit 2, no output", "[outputs]") {
  const std::string base = R"(name: m
parameters:
  l: 2.0
bodies:
  - name: crank
    q0: [0, 0, 0]
joints:
  - type: revolute
    i: ground
    j: crank
drivers:
  - type: absolute_angle
    body: crank
    f: "t"
points:
  - name: tip
    body: crank
    s: [1, 0]
outputs:
)";  // the outputs start on line 20
  struct Case {
    const char* name;
    std::string outputs;
    const char* item;
    int line;
    const char* message;
  };
  const std::vector<Case> cases = {
      // Velocities are allowed (as in loads), but not a velocity of nothing, and a rate
      // spelt otherwise is pointed to the format's name.
      {"velocity_of_nothing", "  ok: \"xd_crank\"\n  w: \"phid_nothing\"\n", "outputs.w", 21,
       "unknown symbol 'phid_nothing'"},
      {"rate_spelling", "  w: \"1 + 2*omega_crank\"\n", "outputs.w", 20,
       "it reads as a rate of 'phi_crank', whose velocity is 'phid_crank'"},
      {"unknown", "  u: \"2*nothing\"\n", "outputs.u", 20, "unknown symbol 'nothing'"},
      {"clash_body", "  crank: \"phi_crank\"\n", "outputs.crank", 20, "clashes"},
      {"clash_point", "  tip: \"phi_crank\"\n", "outputs.tip", 20, "clashes"},
      {"clash_parameter", "  l: \"phi_crank\"\n", "outputs.l", 20, "clashes"},
      {"clash_coordinate", "  x_crank: \"phi_crank\"\n", "outputs.x_crank", 20, "clashes"},
      {"duplicate", "  o: \"t\"\n  o: \"t\"\n", "outputs.o", 21, "duplicate"},
      {"not_a_mapping", "  - \"t\"\n", "outputs", 20, "mapping"},
  };
  for (const Case& c : cases) {
    SECTION(c.name) {
      const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "outputs_hostile" / c.name;
      fs::remove_all(dir);
      fs::create_directories(dir);
      const fs::path mech = dir / "m.yaml";
      std::ofstream(mech) << base << c.outputs;
      const fs::path csv = dir / "m.csv", gen = dir / "gen";
      fs::create_directories(gen);
      for (const auto& args :
           std::vector<std::vector<std::string>>{{"analyze", mech.string(), "--t0", "0", "--t1",
                                                  "1", "--steps", "2", "-o", csv.string()},
                                                 {"generate", mech.string(), "-o", gen.string()},
                                                 {"eval", mech.string()}}) {
        const auto r = run_kinegen(args);
        INFO(args[0] << " stderr: " << r.err);
        CHECK(r.exit_code == 2);
        CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
        CHECK(r.err.rfind("error: " + mech.string() + ":" + std::to_string(c.line) + ": " + c.item,
                          0) == 0);
        CHECK(r.err.find(c.message) != std::string::npos);
        CHECK(r.out.empty());
      }
      CHECK(!fs::exists(csv));
      CHECK(fs::is_empty(gen));
    }
  }
}

TEST_CASE("headers of files without outputs have no outputs function", "[outputs]") {
  std::ifstream in(std::string(KINEGEN_SOURCE_DIR) + "/generated/four_bar.hpp");
  std::stringstream text;
  text << in.rdbuf();
  CHECK(text.str().find("struct four_bar") != std::string::npos);
  CHECK(text.str().find("num_outputs") == std::string::npos);
}

namespace {

const std::string kVelocityOutputs =
    std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/slider_crank_velocity_outputs.yaml";
const double kNan = std::numeric_limits<double>::quiet_NaN();

// slide = xd_rod, spin = phid_rod x_rod, energy = (xd_rod^2 + yd_rod^2)/2 + t phid_crank,
// stroke = x_rod - (l - 1), from the closed-form slider-crank (l = 2, omega = 1): v by the chain
// rule with the closed-form accelerations; a nan but for the position output.
std::vector<Triple> velocity_outputs_truth(double t) {
  const cf::SliderCrankParams p;
  const auto st = cf::slider_crank_state(t, p);
  const double x2 = st.q[3], v2 = st.qd[3], a2 = st.qdd[3], w2 = st.qd[5], al2 = st.qdd[5];
  return {{v2, a2, kNan},
          {w2 * x2, al2 * x2 + w2 * v2, kNan},
          {v2 * v2 / 2 + t * p.omega, v2 * a2 + p.omega, kNan},
          {x2 - (p.l - 1), v2, a2}};
}

// The largest difference of value and v relative to 1 + |truth|; a is nan exactly where the
// truth's is, else compared too.
Worst compare_velocity_outputs(const std::vector<Triple>& got, const std::vector<Triple>& want) {
  Worst w;
  REQUIRE(got.size() == want.size());
  for (std::size_t o = 0; o < want.size(); ++o) {
    INFO("output " << o);
    CHECK(std::isnan(got[o][2]) == std::isnan(want[o][2]));
    Triple g = got[o], t = want[o];
    if (std::isnan(t[2])) g[2] = t[2] = 0;
    w.add(g, t);
  }
  return w;
}

}  // namespace

TEST_CASE("outputs that read velocities: exact value and v, nan a, in analyze and the reference",
          "[outputs]") {
  const auto model = kc::CompiledModel::from_file(kVelocityOutputs);
  for (const bool reference : {false, true}) {
    Worst worst;
    int rows = 0;
    const auto sink = [&](const kc::StateRow& row) {
      const Worst w = compare_velocity_outputs(row.outputs, velocity_outputs_truth(row.t));
      worst.value = std::max(worst.value, w.value);
      worst.rate = std::max(worst.rate, w.rate);
      worst.accel = std::max(worst.accel, w.accel);
      ++rows;
    };
    if (reference)
      kc::run_reference_analysis(*model, kTurn, 40, sink);
    else
      kc::run_analysis(*model, kTurn, sink);
    CHECK(rows == kTurn.steps + 1);
    std::printf("velocity outputs vs closed form (%s): value %.2e, v %.2e, stroke's a %.2e\n",
                reference ? "reference" : "double", worst.value, worst.rate, worst.accel);
    CHECK(worst.value < (reference ? 1e-14 : 1e-13));
    CHECK(worst.rate < (reference ? 5e-14 : 1e-12));
    CHECK(worst.accel < (reference ? 1e-14 : 1e-11));
  }
}

TEST_CASE("a velocity output's v is the derivative of its value column (central differences)",
          "[outputs]") {
  // Three rows t0 - h, t0, t0 + h of an analysis: (O(t0 + h) - O(t0 - h)) / 2h = O' + O h^2/6.
  const auto model = kc::CompiledModel::from_file(kVelocityOutputs);
  const double h = 1e-5;
  double worst = 0;
  for (double t0 : {0.3, 1.1, 2.0, 2.9, 4.4, 5.7}) {
    std::vector<kc::StateRow> rows;
    kc::run_analysis(*model, {t0 - h, t0 + h, 2},
                     [&](const kc::StateRow& row) { rows.push_back(row); });
    REQUIRE(rows.size() == 3);
    for (int o = 0; o < 4; ++o) {
      const double diff = (rows[2].outputs[o][0] - rows[0].outputs[o][0]) / (2 * h);
      const double v = rows[1].outputs[o][1];
      worst = std::max(worst, std::abs(diff - v) / (1 + std::abs(v)));
    }
  }
  std::printf("velocity outputs' v vs central differences (h = 1e-5): %.2e\n", worst);
  CHECK(worst < 1e-7);
}

TEST_CASE("analyze's CSV writes nan as a velocity output's .a, also with --reference-digits",
          "[outputs]") {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "outputs_velocity_cli";
  fs::create_directories(dir);
  const std::string csv = (dir / "plain.csv").string(), ref = (dir / "ref.csv").string();
  const std::vector<std::string> grid = {"--t0", "0", "--t1", "3", "--steps", "6"};
  for (const auto& [file, extra] : {std::pair{csv, std::string()}, {ref, std::string("40")}}) {
    auto args = std::vector<std::string>{"analyze", kVelocityOutputs, "-o", file};
    args.insert(args.end(), grid.begin(), grid.end());
    if (!extra.empty()) args.insert(args.end(), {"--reference-digits", extra});
    const auto r = run_kinegen(args);
    INFO(r.err);
    REQUIRE(r.exit_code == 0);
    std::ifstream in(file);
    std::string header;
    std::getline(in, header);
    const std::string tail =
        "rod.alpha,slide,slide.v,slide.a,spin,spin.v,spin.a,energy,energy.v,energy.a,stroke,"
        "stroke.v,stroke.a";
    REQUIRE(header.size() >= tail.size());
    CHECK(header.compare(header.size() - tail.size(), tail.size(), tail) == 0);
    int rows = 0;
    for (std::string line; std::getline(in, line); ++rows) {
      const auto v = split(line, ',');
      const double t = std::stod(v[0]);
      const auto truth = velocity_outputs_truth(t);
      for (std::size_t o = 0; o < truth.size(); ++o)
        for (int d = 0; d < 3; ++d) {
          const std::string& text = v[v.size() - 12 + 3 * o + d];
          INFO("output " << o << " column " << d << " at t = " << t);
          if (std::isnan(truth[o][d])) {
            CHECK(text == "nan");
          } else {
            CHECK(std::abs(std::stod(text) - truth[o][d]) <= 1e-12 * (1 + std::abs(truth[o][d])));
          }
        }
    }
    CHECK(rows == 7);
  }
}

TEST_CASE("eval's outputs read the --qd given", "[outputs]") {
  const double t = 0.8;
  const auto st = cf::slider_crank_state(t);
  const auto list = [](const auto& values) {
    std::string s;
    for (double v : values) {
      char text[40];
      std::snprintf(text, sizeof text, "%.17g", v);
      s += (s.empty() ? "" : ",") + std::string(text);
    }
    return s;
  };
  const auto r =
      run_kinegen({"eval", kVelocityOutputs, "--t", "0.8", "--q", list(st.q), "--qd", list(st.qd)});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  const auto at = r.out.find("\"outputs\": [");
  REQUIRE(at != std::string::npos);
  const auto values = split(r.out.substr(at + 12, r.out.find(']', at) - at - 12), ',');
  const auto truth = velocity_outputs_truth(t);
  REQUIRE(values.size() == truth.size());
  for (std::size_t o = 0; o < truth.size(); ++o)
    CHECK(std::abs(std::stod(values[o]) - truth[o][0]) <= 1e-14 * (1 + std::abs(truth[o][0])));
}

TEST_CASE("the generated header's velocity outputs agree with analyze and the complex step",
          "[outputs]") {
  using Model = kinegen::models::slider_crank_velocity_outputs;
  static_assert(Model::num_outputs == 4);
  const auto model = kc::CompiledModel::from_file(kVelocityOutputs);
  const Model::Params p;
  double worst_analyze = 0, worst_v = 0;
  kc::run_analysis(*model, kTurn, [&](const kc::StateRow& row) {
    std::array<double, 4> value, velocity, acceleration;
    Model::outputs(row.q.data(), row.qd.data(), row.qdd.data(), row.t, p, value.data(),
                   velocity.data(), acceleration.data());
    for (int o = 0; o < 4; ++o) {
      const Triple got{value[o], velocity[o], acceleration[o]};
      CHECK(std::isnan(got[2]) == (o < 3));
      for (int d = 0; d < (o < 3 ? 2 : 3); ++d)
        worst_analyze = std::max(worst_analyze, std::abs(got[d] - row.outputs[o][d]) /
                                                    (1 + std::abs(row.outputs[o][d])));
    }
    // Complex step along the exact motion: Im O(q(t + ih), qd(t + ih), t + ih) / h = dO/dt,
    // independent of the header's O_q qd + O_qd qdd path.
    using C = std::complex<double>;
    const double h = 1e-30;
    const C tc(row.t, h);
    C q[6], qd[6], v[4];
    slider_crank_q(tc, q, qd);
    Model::output_values(q, qd, tc, p, v);
    for (int o = 0; o < 4; ++o)
      worst_v = std::max(worst_v, std::abs(v[o].imag() / h - row.outputs[o][1]) /
                                      (1 + std::abs(row.outputs[o][1])));
  });
  std::printf("generated velocity outputs vs analyze %.2e; analyze's v vs complex step %.2e\n",
              worst_analyze, worst_v);
  CHECK(worst_analyze <= 1e-15);
  CHECK(worst_v < 1e-12);
}

TEST_CASE("simulate: a damper's power as an output, its v the derivative of its column",
          "[outputs]") {
  // four_bar_damped with the damper's power c phid_rocker^2, the free item's rate theta_d and
  // a position output; the power's integral is minus the damper's work (energy.work).
  std::ifstream in(std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/four_bar_damped.yaml");
  std::stringstream text;
  text << in.rdbuf();
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "outputs_velocity_simulate";
  fs::create_directories(dir);
  const fs::path mech = dir / "damped.yaml";
  std::ofstream(mech) << text.str()
                      << "outputs:\n  power: \"damping*phid_rocker^2\"\n  rate: \"theta_d\"\n"
                         "  angle: \"phi_rocker\"\n";
  // The CSV's rows, and the index of a column by name.
  struct Table {
    std::vector<std::string> names;
    std::vector<std::vector<double>> rows;
    std::size_t operator()(const std::string& name) const {
      const auto it = std::find(names.begin(), names.end(), name);
      REQUIRE(it != names.end());
      return static_cast<std::size_t>(it - names.begin());
    }
  };
  const auto simulate = [&](const std::string& t1, int steps, const std::string& digits) {
    const std::string csv = (dir / ("damped" + digits + ".csv")).string();
    std::vector<std::string> args = {
        "simulate", mech.string(), "--t1", t1, "--steps", std::to_string(steps), "-q", "-o", csv};
    if (digits.empty())
      args.insert(args.end(), {"--rtol", "1e-12"});
    else
      args.insert(args.end(), {"--reference", digits});
    const auto r = run_kinegen(args);
    INFO(r.err);
    REQUIRE(r.exit_code == 0);
    std::ifstream rows(csv);
    std::string line;
    std::getline(rows, line);
    Table table{split(line, ','), {}};
    while (std::getline(rows, line)) {
      std::vector<double> v;
      for (const auto& x : split(line, ',')) v.push_back(std::stod(x));  // "nan" reads as NaN
      table.rows.push_back(std::move(v));
    }
    REQUIRE(table.rows.size() == steps + 1u);
    return table;
  };
  const int steps = 4000;
  const double h = 2.0 / steps;
  const Table table = simulate("2", steps, "");
  const std::size_t power = table("power"), omega = table("rocker.omega"),
                    alpha = table("rocker.alpha"), rate = table("rate"),
                    crank_omega = table("crank.omega"), crank_alpha = table("crank.alpha"),
                    work = table("energy.work"), angle = table("angle");
  const double c = 0.5;  // the file's damping
  double worst_exact = 0, worst_central = 0, worst_simpson = 0, largest = 0, largest_v = 0;
  double integral = 0;
  const auto& rows = table.rows;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const auto& row = rows[k];
    // Exact: power = c w^2, its v = 2 c w alpha; rate = crank.omega, its v = crank.alpha.
    const double w = row[omega];
    for (const auto& [got, want] : {std::pair{row[power], c * w * w},
                                    {row[power + 1], 2 * c * w * row[alpha]},
                                    {row[rate], row[crank_omega]},
                                    {row[rate + 1], row[crank_alpha]}})
      worst_exact = std::max(worst_exact, std::abs(got - want) / (1 + std::abs(want)));
    CHECK(std::isnan(row[power + 2]));
    CHECK(std::isnan(row[rate + 2]));
    CHECK(std::isfinite(row[angle + 2]));
    largest = std::max(largest, std::abs(row[power]));
    largest_v = std::max(largest_v, std::abs(row[power + 1]));
    if (k > 0 && k + 1 < rows.size()) {
      // The central difference (error h^2/6 times O''') and Simpson's rule over [t - h, t + h]:
      // O(t + h) - O(t - h) = h/3 (v(t - h) + 4 v(t) + v(t + h)), error h^5/90 times O^(5).
      const double rise = rows[k + 1][power] - rows[k - 1][power];
      worst_central = std::max(worst_central, std::abs(rise / (2 * h) - row[power + 1]));
      const double simpson =
          h / 3 * (rows[k - 1][power + 1] + 4 * row[power + 1] + rows[k + 1][power + 1]);
      worst_simpson = std::max(worst_simpson, std::abs(rise - simpson));
    }
    if (k > 0) integral += h * (row[power] + rows[k - 1][power]) / 2;
  }
  const double work_error = std::abs(integral + rows.back()[work]);
  std::printf(
      "simulate: damper power vs c w^2 and its v vs 2 c w alpha %.2e; v vs central differences "
      "(h = %g) %.2e of max |v| %.2e; Simpson over 2h vs the rise %.2e of max |power| %.2e; "
      "trapezoid integral of the power + energy.work %.2e\n",
      worst_exact, h, worst_central, largest_v, worst_simpson, largest, work_error);
  CHECK(worst_exact < 1e-13);
  CHECK(worst_central < 2e-4 * largest_v);
  CHECK(worst_simpson < 1e-9 * largest);
  CHECK(work_error < 1e-5 * std::abs(rows.back()[work]));

  // The 20-digit reference integration gives the same columns, .a nan.
  const Table ref = simulate("0.2", 2, "20");
  CHECK(ref.names == table.names);
  double worst_reference = 0;
  for (std::size_t k = 0; k < ref.rows.size(); ++k) {
    CHECK(std::isnan(ref.rows[k][power + 2]));
    CHECK(std::isnan(ref.rows[k][rate + 2]));
    for (const std::size_t col : {power, power + 1, rate, rate + 1}) {
      const double want = ref.rows[k][col], got = rows[k * 200][col];
      worst_reference = std::max(worst_reference, std::abs(got - want) / (1 + std::abs(want)));
    }
  }
  std::printf("simulate --reference 20 vs the double run (power, rate and their v): %.2e\n",
              worst_reference);
  CHECK(worst_reference < 1e-9);
}

TEST_CASE("velocity outputs are refused, one line, where they cannot be exact", "[outputs]") {
  // --sensitivity would need dqd/dp (tolerance, which needs no outputs, runs); stop_when
  // cannot read an output's rate that needs qdd.
  const auto r = run_kinegen({"analyze", kVelocityOutputs, "--t0", "0", "--t1", "1", "--steps", "2",
                              "--sensitivity", "l"});
  CHECK(r.exit_code == 2);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK(r.err.rfind("error: " + kVelocityOutputs + ":34: outputs.slide: --sensitivity:", 0) == 0);
  CHECK(r.out.empty());
  // tolerance needs the positions' sensitivities only: it runs.
  const auto tol = run_kinegen(
      {"tolerance", kVelocityOutputs, "--tol", "l=0.01", "--t0", "0", "--t1", "1", "--steps", "2"});
  INFO(tol.err);
  CHECK(tol.exit_code == 0);

  std::ifstream in(std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/pendulum.yaml");
  std::stringstream text;
  text << in.rdbuf();
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "outputs_velocity_stop";
  fs::create_directories(dir);
  for (const auto& [stop, ok] : {std::pair{"spin.v - 1", false}, {"spin - 1", true}}) {
    const fs::path mech = dir / (ok ? "ok.yaml" : "bad.yaml");
    std::ofstream(mech) << text.str() << "outputs:\n  spin: \"phid_rod^2\"\nstop_when: \"" << stop
                        << "\"\n";
    const auto s = run_kinegen({"simulate", mech.string(), "--t1", "2", "--steps", "4", "-q"});
    INFO(stop << ": " << s.err);
    if (ok) {
      // The rod swings down from horizontal: phid^2 reaches 1 before the bottom.
      CHECK(s.exit_code == 0);
      CHECK(s.err.find("stopped at t = ") != std::string::npos);
    } else {
      CHECK(s.exit_code == 2);
      CHECK(std::count(s.err.begin(), s.err.end(), '\n') == 1);
      CHECK(s.err.find(": stop_when: 'spin.v' is the rate of an output that reads velocities") !=
            std::string::npos);
    }
  }
}
