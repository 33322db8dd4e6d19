// Drivers in pieces, with a period, from tables and as run-time inputs, against
// independent truths: the motion laws' formulas on grids that land exactly on the pieces'
// boundaries, a cubic that a table sampled from it must reproduce to rounding, a periodic
// law's repetition with its rise, the generated header fed the exact inputs against
// `analyze --input`; and every hostile input with its one error line.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "pieces_drive.hpp"
#include "support/run_command.hpp"

namespace {

namespace kc = kinegen::codegen;
namespace fs = std::filesystem;
using kinegen::test::CommandResult;

constexpr double kPi = 3.14159265358979323846;

std::string source_dir() { return KINEGEN_SOURCE_DIR; }
std::string drive_file() { return source_dir() + "/tests/mechanisms/pieces_drive.yaml"; }
std::string lift_file() { return source_dir() + "/tests/mechanisms/pieces_lift.csv"; }

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

std::unique_ptr<kc::CompiledModel> drive_model() {
  kc::BuildOptions build;
  build.inputs = {{"stroke", lift_file()}};
  build.inputs_required = true;
  return kc::CompiledModel::from_file(drive_file(), {}, build);
}

// The cubic pieces_lift.csv is sampled from, and its derivatives.
double lift(double t) { return 0.2 + 0.5 * t - 0.1 * t * t + 0.03 * t * t * t; }
double lift_v(double t) { return 0.5 - 0.2 * t + 0.09 * t * t; }
double lift_a(double t) { return -0.2 + 0.18 * t; }

// The shaft's law of pieces_drive.yaml (and the first test's slider) over one period (h = 0.5, T =
// 4), by the formulas of the spec: dwell, cycloidal rise on [1, 2), dwell, 3-4-5 return on [3, 4);
// a time at a boundary takes the later piece.
void shaft_law(double t, double f[3]) {
  const double h = 0.5, T = 4;
  const double local = t - T * std::floor(t / T);
  f[0] = f[1] = f[2] = 0;
  if (local < 1) return;
  if (local < 2) {
    const double x = local - 1;
    f[0] = h * (x - std::sin(2 * kPi * x) / (2 * kPi));
    f[1] = h * (1 - std::cos(2 * kPi * x));
    f[2] = h * 2 * kPi * std::sin(2 * kPi * x);
    return;
  }
  if (local < 3) {
    f[0] = h;
    return;
  }
  const double x = local - 3;
  f[0] = h - h * (10 * std::pow(x, 3) - 15 * std::pow(x, 4) + 6 * std::pow(x, 5));
  f[1] = -h * (30 * x * x - 60 * std::pow(x, 3) + 30 * std::pow(x, 4));
  f[2] = -h * (60 * x - 180 * x * x + 120 * std::pow(x, 3));
}

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "pieces" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

CommandResult run_kinegen(std::vector<std::string> args) {
  args.insert(args.begin(), KINEGEN_EXE);
  return kinegen::test::run_command(args);
}

// A one-slider mechanism whose driver is `law` (the YAML lines after `body: slider`).
std::string slider(const std::string& law) {
  return "name: slider\n"
         "parameters:\n"
         "  T: 4\n"
         "bodies:\n"
         "  - name: slider\n"
         "    q0: [0, 0, 0]\n"
         "joints:\n"
         "  - type: absolute_y\n"
         "    body: slider\n"
         "    value: 0\n"
         "  - type: absolute_angle\n"
         "    body: slider\n"
         "    value: 0\n"
         "drivers:\n"
         "  - type: absolute_x\n"
         "    body: slider\n" +
         law;
}

}  // namespace

TEST_CASE("pieces: a periodic dwell-rise-dwell-return law against its formulas on its boundaries",
          "[pieces]") {
  const auto model = kc::CompiledModel::from_mechanism(
      kc::parse_mechanism(slider("    period: T\n"
                                 "    f:\n"
                                 "      - {until: 1, f: \"0\"}\n"
                                 "      - {until: 2, f: \"0.5*cycloidal(t - 1)\"}\n"
                                 "      - {until: 3, f: \"0.5\"}\n"
                                 "      - {f: \"0.5 - 0.5*poly345(t - 3)\"}\n"),
                          "cam.yaml"));
  // 8 steps per second over three periods: every boundary (1, 2, 3 and the seams 4, 8) is a
  // grid time.
  const Run run = analyze(*model, {0, 12, 96});
  REQUIRE(run.rows.size() == 97);
  double worst = 0;
  for (const auto& r : run.rows) {
    double f[3];
    shaft_law(r.t, f);
    // Each period adds f(T) - f(0) = 0 here; the angle repeats.
    worst = std::max({worst, std::abs(r.q[0] - f[0]), std::abs(r.qd[0] - f[1]) / 10,
                      std::abs(r.qdd[0] - f[2]) / 100});
  }
  INFO("largest difference " << worst);
  CHECK(worst <= 1e-13);
  // The cycloid's and 3-4-5's ends rest (f' = f'' = 0): no warning.
  CHECK(model->symbolic().warnings.empty());
}

TEST_CASE("pieces: a jump in f is an error, in f' or f'' a warning naming the boundary",
          "[pieces]") {
  const std::string jump = slider(
      "    f:\n"
      "      - {until: 1, f: \"t\"}\n"
      "      - {f: \"2\"}\n");
  try {
    (void)kc::CompiledModel::from_mechanism(kc::parse_mechanism(jump, "jump.yaml"));
    FAIL("a jump in f was accepted");
  } catch (const kc::InputError& e) {
    const std::string what = e.what();
    CHECK(e.item() == "drivers[0] (absolute_x)");
    CHECK(e.loc().line == 19);
    CHECK(what.find("f jumps at the boundary t = 1: 1 before it, 2 after it") != std::string::npos);
  }
  // Velocity jumps from 1 to 0 at t = 1 and acceleration (0 to 2) at t = 2.
  const std::string kinks = slider(
      "    f:\n"
      "      - {until: 1, f: \"t\"}\n"
      "      - {until: 2, f: \"1\"}\n"
      "      - {f: \"1 + (t - 2)^2\"}\n");
  const auto model = kc::CompiledModel::from_mechanism(kc::parse_mechanism(kinks, "kinks.yaml"));
  const auto& w = model->symbolic().warnings;
  REQUIRE(w.size() == 2);
  CHECK(w[0].find("f' jumps at the boundary t = 1: 1 before it, 0 after it") != std::string::npos);
  CHECK(w[1].find("f'' jumps at the boundary t = 2: 0 before it, 2 after it") != std::string::npos);
  // The analysis runs through the kinks (the jump check accepts the one-sided motion there),
  // and each piece has its own derivatives, the later one at a boundary.
  const Run run = analyze(*model, {0, 3, 12});
  REQUIRE(run.rows.size() == 13);
  for (const auto& r : run.rows) {
    const double t = r.t;
    const double x = t < 1 ? t : t < 2 ? 1 : 1 + (t - 2) * (t - 2);
    const double v = t < 1 ? 1 : t < 2 ? 0 : 2 * (t - 2);
    const double a = t < 2 ? 0 : 2;
    CAPTURE(t);
    CHECK(r.q[0] == Approx(x).margin(1e-14));
    CHECK(r.qd[0] == Approx(v).margin(1e-14));
    CHECK(r.qdd[0] == Approx(a).margin(1e-14));
  }
}

TEST_CASE("pieces: each period adds f(T) - f(0)", "[pieces]") {
  // A ratchet: rises by 1 over [0, 1), dwells; every period of 2 adds 1.
  const std::string yaml = slider(
      "    period: 2\n"
      "    f:\n"
      "      - {until: 1, f: \"harmonic(t)\"}\n"
      "      - {f: \"1\"}\n");
  const auto model = kc::CompiledModel::from_mechanism(kc::parse_mechanism(yaml, "ratchet.yaml"));
  // harmonic's acceleration jumps at its ends: warnings at t = 1 and at the seam.
  CHECK(model->symbolic().warnings.size() == 2);
  const Run run = analyze(*model, {0, 8, 64});
  for (const auto& r : run.rows) {
    const double turns = std::floor(r.t / 2), local = r.t - 2 * turns;
    const double x = turns + (local < 1 ? (1 - std::cos(kPi * local)) / 2 : 1);
    CAPTURE(r.t);
    CHECK(r.q[0] == Approx(x).margin(1e-14));
    CHECK(r.qd[0] == Approx(local < 1 ? kPi / 2 * std::sin(kPi * local) : 0).margin(1e-13));
  }
}

TEST_CASE("tables: a table sampled from a cubic is reproduced to rounding", "[pieces]") {
  const auto model = drive_model();
  // 97 times, knots and between them, up to the table's last t.
  const Run run = analyze(*model, {0, 3, 96});
  double worst = 0;
  for (const auto& r : run.rows) {
    const double t = r.t;
    for (int b : {3, 6})  // the table's slider, and the input's (interpolated as a table)
      worst = std::max({worst, std::abs(r.q[b] - lift(t)), std::abs(r.qd[b] - lift_v(t)),
                        std::abs(r.qdd[b] - lift_a(t))});
  }
  INFO("largest difference from the cubic " << worst);
  CHECK(worst <= 1e-13);
}

TEST_CASE("tables: a periodic table repeats with its rise and is smooth at the seam", "[pieces]") {
  const fs::path dir = scratch("periodic");
  // 0.3 t + 0.1 sin(pi t) over one period of 2 (rise 0.6), 33 knots.
  std::string csv = "t,value\n";
  for (int k = 0; k <= 32; ++k) {
    const double t = 2.0 * k / 32;
    csv += kc::format_number(t) + "," + kc::format_number(0.3 * t + 0.1 * std::sin(kPi * t)) + "\n";
  }
  write_text(dir / "wave.csv", csv);
  write_text(dir / "m.yaml", slider("    period: 2\n    table: wave.csv\n"));
  const auto model = kc::CompiledModel::from_file((dir / "m.yaml").string());
  const Run run = analyze(*model, {-2, 6, 64});
  double worst[3] = {0, 0, 0};
  for (const auto& r : run.rows) {
    const double t = r.t;
    worst[0] = std::max(worst[0], std::abs(r.q[0] - (0.3 * t + 0.1 * std::sin(kPi * t))));
    worst[1] = std::max(worst[1], std::abs(r.qd[0] - (0.3 + 0.1 * kPi * std::cos(kPi * t))));
    worst[2] = std::max(worst[2], std::abs(r.qdd[0] + 0.1 * kPi * kPi * std::sin(kPi * t)));
  }
  INFO("largest differences " << worst[0] << " " << worst[1] << " " << worst[2]);
  // A cubic spline of h = 1/16 on a sine: errors O(h^4), O(h^3), O(h^2).
  CHECK(worst[0] <= 1e-6);
  CHECK(worst[1] <= 2e-5);
  CHECK(worst[2] <= 5e-3);
  // Rows one period apart differ by exactly the rise's multiples (to rounding).
  for (std::size_t k = 0; k + 16 < run.rows.size(); ++k) {
    CHECK(run.rows[k + 16].q[0] - run.rows[k].q[0] == Approx(0.6).margin(1e-14));
    CHECK(run.rows[k + 16].qd[0] == Approx(run.rows[k].qd[0]).margin(1e-13));
  }
}

TEST_CASE("inputs: the generated header fed the exact inputs agrees with analyze --input",
          "[pieces][generated]") {
  using M = kinegen::models::pieces_drive;
  const auto model = drive_model();
  const Run run = analyze(*model, {0, 3, 60});
  M::Params p{};
  double q[M::nq], qd[M::nq] = {}, qdd[M::nq] = {};
  for (int k = 0; k < M::nq; ++k) q[k] = M::q0[k];
  double worst = 0;
  for (const auto& r : run.rows) {
    p.stroke = lift(r.t);
    p.stroke_v = lift_v(r.t);
    p.stroke_a = lift_a(r.t);
    const auto report = M::solve_step(q, r.t, p, qd, qdd, M::BlockOptions{});
    REQUIRE(report.status == 0);
    for (int c = 0; c < M::nq; ++c)
      worst = std::max(
          {worst, std::abs(q[c] - r.q[c]), std::abs(qd[c] - r.qd[c]), std::abs(qdd[c] - r.qdd[c])});
    // The input slider follows the inputs exactly.
    CHECK(q[6] == p.stroke);
    CHECK(qd[6] == p.stroke_v);
    CHECK(qdd[6] == p.stroke_a);
  }
  INFO("largest difference " << worst);
  CHECK(worst <= 1e-12);
  // Outside the table's range the generated code fails (a NaN the solver reports), never
  // extrapolates.
  const auto report = M::solve_step(q, 3.5, p, qd, qdd, M::BlockOptions{});
  CHECK(report.status != 0);
}

TEST_CASE("tables: a run past the table's end fails there with exit 1, earlier rows kept",
          "[pieces][cli]") {
  const fs::path dir = scratch("past_end");
  const fs::path csv = dir / "out.csv";
  const auto r = run_kinegen({"analyze", drive_file(), "--input", "stroke=" + lift_file(), "--t0",
                              "0", "--t1", "4", "--steps", "8", "-o", csv.string()});
  INFO(r.err);
  CHECK(r.exit_code == 1);
  CHECK(r.err.rfind("error: ", 0) == 0);
  CHECK(r.err.find("at t = 3.5") != std::string::npos);
  CHECK(r.err.find("pieces_lift.csv") != std::string::npos);
  std::ifstream in(csv);
  int lines = 0;
  for (std::string line; std::getline(in, line);) ++lines;
  CHECK(lines == 1 + 7);  // header, t = 0 ... 3
  // Without --input, an input driver is a usage error.
  const auto u = run_kinegen({"analyze", drive_file(), "--t0", "0", "--t1", "1", "--steps", "2"});
  CHECK(u.exit_code == 2);
  CHECK(u.err.find("--input stroke=FILE.csv") != std::string::npos);
}

TEST_CASE("pieces and tables: every hostile input gives one error line, exit 2, no output",
          "[pieces][hostile]") {
  struct Case {
    const char* name;
    std::string law;  // YAML after `body: slider`
    std::string csv;  // data.csv's content ("" : none written)
    int line;
    const char* message;
  };
  const std::string good = "t,value\n0,0\n1,1\n2,4\n3,9\n";
  const std::vector<Case> cases = {
      {"missing", "    table: data.csv\n", "", 17, "does not exist"},
      {"empty", "    table: data.csv\n", " ", 17, "empty"},
      {"not_numeric", "    table: data.csv\n", "t,value\n0,0\n1,one\n2,4\n3,9\n", 17,
       "line 3 is not two numbers"},
      {"not_increasing", "    table: data.csv\n", "t,value\n0,0\n1,1\n1,4\n3,9\n", 17,
       "t must increase strictly"},
      {"short", "    table: data.csv\n", "t,value\n0,0\n1,1\n2,4\n", 17, "at least 4"},
      {"nan", "    table: data.csv\n", "t,value\n0,0\n1,nan\n2,4\n3,9\n", 17, "not finite"},
      {"escapes", "    table: ../data.csv\n", good, 17, "outside the mechanism's folder"},
      {"link", "    table: link.csv\n", good, 17, "outside the mechanism's folder"},
      {"period_zero", "    period: 0\n    f:\n      - {until: 1, f: \"t\"}\n      - {f: \"1\"}\n",
       "", 17, "period must be greater than 0"},
      {"period_negative", "    period: -T\n    table: data.csv\n", good, 17,
       "period must be greater than 0"},
      {"table_period", "    period: 2\n    table: data.csv\n", good, 17,
       "period must be its last t"},
      {"out_of_order",
       "    f:\n      - {until: 2, f: \"t\"}\n      - {until: 1, f: \"2\"}\n      - {f: \"2\"}\n",
       "", 19, "pieces out of order"},
      {"until_outside_period",
       "    period: 2\n    f:\n      - {until: 3, f: \"t\"}\n      - {f: \"3\"}\n", "", 19,
       "must lie inside (0, period)"},
      {"last_piece_until", "    f:\n      - {until: 1, f: \"t\"}\n      - {until: 2, f: \"1\"}\n",
       "", 19, "unknown key 'until'"},
      {"f_and_table", "    f: t\n    table: data.csv\n", good, 18, "either f or table"},
      {"input_without_name", "    f: input\n", "", 17, "needs a name"},
  };
  for (const Case& c : cases) {
    SECTION(c.name) {
      const fs::path dir = scratch(c.name) / "mech";
      fs::create_directories(dir);
      if (!c.csv.empty()) {
        write_text(dir / "data.csv", c.csv);
        write_text(dir.parent_path() / "data.csv", good);
        fs::create_symlink(dir.parent_path() / "data.csv", dir / "link.csv");
      }
      const fs::path mech = dir / "m.yaml";
      write_text(mech, slider(c.law));
      const fs::path out = dir.parent_path() / "out";
      fs::create_directories(out);
      for (const std::vector<std::string>& args :
           {std::vector<std::string>{"generate", mech.string(), "-o", out.string()},
            {"analyze", mech.string(), "--t0", "0", "--t1", "1", "--steps", "2", "-o",
             (out / "m.csv").string()}}) {
        const auto r = run_kinegen(args);
        INFO("stderr: " << r.err);
        CHECK(r.exit_code == 2);
        CHECK(r.err.rfind("error: " + mech.string() + ":" + std::to_string(c.line) +
                              ": drivers[0] (absolute_x)",
                          0) == 0);
        CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
        CHECK(r.err.find(c.message) != std::string::npos);
        CHECK(r.out.empty());
      }
      CHECK(fs::is_empty(out));
    }
  }
}

TEST_CASE("pieces: a driver of 1000 pieces loads and follows its formula", "[pieces]") {
  // A staircase of 999 cycloidal rises: the derivatives of the nested choice grow linearly.
  std::string law = "    f:\n";
  for (int k = 0; k < 999; ++k)
    law += "      - {until: " + std::to_string(k + 1) + ", f: \"" + std::to_string(k) +
           " + cycloidal(t - " + std::to_string(k) + ")\"}\n";
  law += "      - {f: \"999\"}\n";
  const auto model = kc::CompiledModel::from_mechanism(kc::parse_mechanism(slider(law), "s.yaml"));
  CHECK(model->symbolic().warnings.empty());
  const Run run = analyze(*model, {0, 1000, 4000});
  double worst = 0;
  for (const auto& r : run.rows) {
    const double k = std::min(std::floor(r.t), 999.0), x = r.t >= 999 ? 0 : r.t - k;
    const double f = k + x - std::sin(2 * kPi * x) / (2 * kPi);
    const double v = r.t >= 999 ? 0 : 1 - std::cos(2 * kPi * x);
    worst = std::max({worst, std::abs(r.q[0] - f) / (1 + k), std::abs(r.qd[0] - v)});
  }
  INFO("largest difference " << worst);
  CHECK(worst <= 1e-13);
}
