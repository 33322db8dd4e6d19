// End-to-end tests of the kinegen binary against the outward contract
// (docs/format.md, Commands): CSV layout of `analyze`, JSON of `eval`,
// what `generate` writes, exit statuses 0/1/2, one `error:` line per failure, and no output
// file left behind by bad input.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "support/closed_form.hpp"
#include "support/files.hpp"
#include "support/run_command.hpp"

namespace {

namespace fs = std::filesystem;
using kinegen::test::read_text;
using kinegen::test::write_text;
namespace kc = kinegen::codegen;
using kinegen::test::CommandResult;

// ---------------------------------------------------------------------------------------------
// Files and processes.

fs::path example(const std::string& name) {
  return fs::path(KINEGEN_SOURCE_DIR) / "examples" / (name + ".yaml");
}

// Every mechanism the repository ships: the examples and the strict-compile test mechanisms.
std::vector<fs::path> yaml_files(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.path().extension() == ".yaml") files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

// A fresh, empty directory for one test.
fs::path scratch_dir(const std::string& name) { return kinegen::test::scratch_dir("cli", name); }

// `text` with the one occurrence of `from` replaced by `to`.
std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  REQUIRE(text.find(from, at + 1) == std::string::npos);
  return text.replace(at, from.size(), to);
}

// The names in a directory, sorted: shows stray temporary or partial files too.
std::vector<std::string> entries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename());
  std::sort(names.begin(), names.end());
  return names;
}

CommandResult kinegen(const std::vector<std::string>& args, const std::string& cwd = {}) {
  std::vector<std::string> argv{KINEGEN_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  return kinegen::test::run_command(argv, cwd);
}

// The contract for every failure: standard error is exactly one line beginning "error: ".
void require_one_error_line(const CommandResult& r) {
  INFO("stderr: " << r.err);
  REQUIRE(r.err.rfind("error: ", 0) == 0);
  REQUIRE(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  REQUIRE(r.err.back() == '\n');
}

std::vector<std::string> split(const std::string& text, char sep) {
  std::vector<std::string> parts;
  std::string part;
  std::istringstream in(text);
  while (std::getline(in, part, sep)) parts.push_back(part);
  if (!text.empty() && text.back() == sep && sep != '\n') parts.push_back("");
  return parts;
}

struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};

Csv parse_csv(const std::string& text) {
  REQUIRE(!text.empty());
  REQUIRE(text.back() == '\n');
  const auto lines = split(text, '\n');
  Csv csv;
  csv.header = split(lines.at(0), ',');
  for (std::size_t k = 1; k < lines.size(); ++k) {
    csv.rows.push_back(split(lines[k], ','));
    REQUIRE(csv.rows.back().size() == csv.header.size());
  }
  return csv;
}

// Parses a whole CSV field as a double.
double number(const std::string& field) {
  char* end = nullptr;
  const double v = std::strtod(field.c_str(), &end);
  INFO("field '" << field << "'");
  REQUIRE(!field.empty());
  REQUIRE(end == field.c_str() + field.size());
  return v;
}

// The columns the spec prescribes, written out independently of the tool's csv_header.
std::vector<std::string> spec_columns(const kc::Mechanism& m) {
  std::vector<std::string> columns{"t"};
  for (const auto& b : m.bodies)
    for (const char* c : {"x", "y", "phi", "vx", "vy", "omega", "ax", "ay", "alpha"})
      columns.push_back(b.name + "." + c);
  for (const auto& p : m.points)
    for (const char* c : {"x", "y", "vx", "vy", "ax", "ay"}) columns.push_back(p.name + "." + c);
  return columns;
}

// The value of the first `t = <number>` in an error message.
double time_in_message(const std::string& message) {
  std::smatch match;
  const std::regex time_re(R"(\bt\s*=\s*([-+0-9.eE]+))");
  INFO("message: " << message);
  REQUIRE(std::regex_search(message, match, time_re));
  return number(match[1]);
}

// ---------------------------------------------------------------------------------------------
// A minimal JSON reader for `eval`: objects, arrays, numbers and null (no string values).

struct Json {
  enum class Kind { kNull, kNumber, kArray, kObject } kind = Kind::kNull;
  double value = 0;
  std::vector<Json> items;
  std::vector<std::pair<std::string, Json>> fields;  // in order of appearance

  const Json& at(const std::string& key) const {
    for (const auto& [k, v] : fields)
      if (k == key) return v;
    throw std::runtime_error("JSON: no key '" + key + "'");
  }
};

class JsonReader {
 public:
  explicit JsonReader(std::string text) : text_(std::move(text)) {}

  Json document() {
    Json v = value();
    skip_space();
    if (pos_ != text_.size()) fail("text after the value");
    return v;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error("JSON: " + what + " at offset " + std::to_string(pos_));
  }
  void skip_space() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
  }
  bool take(char c) {
    skip_space();
    if (pos_ < text_.size() && text_[pos_] == c) return ++pos_, true;
    return false;
  }
  void expect(char c) {
    if (!take(c)) fail(std::string("expected '") + c + "'");
  }

  Json value() {
    skip_space();
    if (pos_ >= text_.size()) fail("unexpected end");
    Json v;
    const char c = text_[pos_];
    if (c == '{') {
      v.kind = Json::Kind::kObject;
      ++pos_;
      if (take('}')) return v;
      do {
        std::string key = string();
        for (const auto& f : v.fields)
          if (f.first == key) fail("duplicate key '" + key + "'");
        expect(':');
        v.fields.emplace_back(std::move(key), value());
      } while (take(','));
      expect('}');
    } else if (c == '[') {
      v.kind = Json::Kind::kArray;
      ++pos_;
      if (take(']')) return v;
      do v.items.push_back(value());
      while (take(','));
      expect(']');
    } else if (text_.compare(pos_, 4, "null") == 0) {
      pos_ += 4;
    } else if (c == '-' || std::isdigit(static_cast<unsigned char>(c))) {  // no nan/inf in JSON
      char* end = nullptr;
      v.kind = Json::Kind::kNumber;
      v.value = std::strtod(text_.c_str() + pos_, &end);
      pos_ = static_cast<std::size_t>(end - text_.c_str());
    } else {
      fail("unexpected character");
    }
    return v;
  }

  std::string string() {
    expect('"');
    const std::size_t close = text_.find('"', pos_);
    if (close == std::string::npos) fail("unterminated string");
    std::string s = text_.substr(pos_, close - pos_);
    if (s.find('\\') != std::string::npos) fail("escapes are not expected in keys");
    pos_ = close + 1;
    return s;
  }

  std::string text_;
  std::size_t pos_ = 0;
};

std::vector<double> numbers(const Json& array) {
  REQUIRE(array.kind == Json::Kind::kArray);
  std::vector<double> values;
  for (const auto& item : array.items) {
    REQUIRE(item.kind == Json::Kind::kNumber);
    values.push_back(item.value);
  }
  return values;
}

struct EvalOutput {
  std::vector<double> phi, nu, gamma;
  std::vector<std::vector<double>> phi_q;
};

// Parses `eval` output: exactly one JSON object with exactly the four keys of the spec.
EvalOutput parse_eval(const std::string& out) {
  Json doc;
  try {
    doc = JsonReader(out).document();
  } catch (const std::exception& e) {
    FAIL(e.what() << "\n" << out);
  }
  REQUIRE(doc.kind == Json::Kind::kObject);
  std::vector<std::string> keys;
  for (const auto& f : doc.fields) keys.push_back(f.first);
  std::sort(keys.begin(), keys.end());
  REQUIRE(keys == std::vector<std::string>{"gamma", "nu", "phi", "phi_q"});
  EvalOutput e;
  e.phi = numbers(doc.at("phi"));
  e.nu = numbers(doc.at("nu"));
  e.gamma = numbers(doc.at("gamma"));
  REQUIRE(doc.at("phi_q").kind == Json::Kind::kArray);
  for (const auto& row : doc.at("phi_q").items) e.phi_q.push_back(numbers(row));
  return e;
}

// Close enough for values printed with 17 significant digits, or with slightly fewer.
void require_close(const std::vector<double>& actual, const std::vector<double>& expected,
                   double margin = 1e-14) {
  REQUIRE(actual.size() == expected.size());
  for (std::size_t k = 0; k < actual.size(); ++k) {
    INFO("index " << k);
    CHECK(actual[k] == Approx(expected[k]).epsilon(1e-14).margin(margin));
  }
}

// ---------------------------------------------------------------------------------------------
// Mechanisms written by the tests.

// The slider-crank of examples/slider_crank.yaml without its driver: 5 equations for 6
// coordinates.
constexpr const char* kUnderDriven = R"(name: under_driven
parameters:
  l: 2.0
bodies:
  - name: crank
    q0: [0.0, 0.0, 0.0]
  - name: rod
    q0: [3.0, 0.0, 1.57]
joints:
  - type: revolute
    i: ground
    j: crank
    si: [0, 0]
    sj: [0, 0]
  - type: revolute
    i: rod
    j: crank
    si: [0, "l"]
    sj: [1, 0]
  - type: absolute_y
    body: rod
    value: 0
)";

// A unit bar pinned at the origin whose tip is pulled along x by 0.3 t: it assembles while
// 0.3 t <= 1, so on the grid t = 0, 1, 2, 3, 4 it solves t = 0..3 and cannot assemble at t = 4.
constexpr const char* kReach = R"(name: reach
bodies:
  - name: bar
    q0: [0, 0, 1.5]
joints:
  - type: revolute
    i: ground
    j: bar
    si: [0, 0]
    sj: [0, 0]
drivers:
  - type: absolute_x
    body: bar
    s: [1, 0]
    f: "0.3*t"
)";

const std::vector<std::string> kExamples = {"four_bar", "offset_slider_crank", "quick_return",
                                            "slider_crank", "slider_crank_lecture"};

// ---------------------------------------------------------------------------------------------
// analyze

TEST_CASE("analyze writes the spec's CSV header and N + 1 rows for every example", "[cli]") {
  for (const auto& name : kExamples) {
    INFO(name);
    const auto r =
        kinegen({"analyze", example(name).string(), "--t0", "0", "--t1", "1", "--steps", "4"});
    INFO("stderr: " << r.err);
    REQUIRE(r.exit_code == 0);
    REQUIRE(r.err.find("error") == std::string::npos);
    const Csv csv = parse_csv(r.out);
    CHECK(csv.header == spec_columns(kc::load_mechanism(example(name).string())));
    CHECK(csv.rows.size() == 5);
  }
}

TEST_CASE("analyze lists bodies in file order, then points, with the spec's column names",
          "[cli]") {
  // Spelled out once by hand, so a mistake shared by spec_columns and the tool would show.
  const auto r = kinegen(
      {"analyze", example("slider_crank").string(), "--t0", "0", "--t1", "0", "--steps", "0"});
  REQUIRE(r.exit_code == 0);
  CHECK(split(r.out, '\n').at(0) ==
        "t,crank.x,crank.y,crank.phi,crank.vx,crank.vy,crank.omega,crank.ax,crank.ay,"
        "crank.alpha,rod.x,rod.y,rod.phi,rod.vx,rod.vy,rod.omega,rod.ax,rod.ay,rod.alpha,"
        "tip.x,tip.y,tip.vx,tip.vy,tip.ax,tip.ay,slider.x,slider.y,slider.vx,slider.vy,"
        "slider.ax,slider.ay");
}

TEST_CASE("analyze samples t_k = T0 + k (T1 - T0) / N and prints 17 significant digits", "[cli]") {
  const double t0 = 0.1, t1 = 0.7;
  const int n = 6;
  const auto r = kinegen({"analyze", example("slider_crank").string(), "--t0", "0.1", "--t1", "0.7",
                          "--steps", std::to_string(n)});
  REQUIRE(r.exit_code == 0);
  const Csv csv = parse_csv(r.out);
  REQUIRE(csv.rows.size() == n + 1);
  // 0.1 is not a double; 17 significant digits show the double nearest to it.
  CHECK(csv.rows[0][0] == "0.10000000000000001");
  for (int k = 0; k <= n; ++k) {
    INFO("row " << k);
    const double t = number(csv.rows[k][0]);
    CHECK(t == Approx(t0 + k * (t1 - t0) / n).epsilon(1e-15));
    for (const auto& field : csv.rows[k]) {
      // %.17g of the value read back reproduces the field: nothing was rounded away.
      char again[40];
      std::snprintf(again, sizeof again, "%.17g", number(field));
      CHECK(field == again);
    }
  }
}

TEST_CASE("analyze reproduces the closed-form slider-crank over two turns", "[cli]") {
  // Two full turns: the crank angle must keep growing to 4 pi (angles are not wrapped).
  const auto r = kinegen({"analyze", example("slider_crank").string(), "--t0", "0", "--t1",
                          "12.566370614359172", "--steps", "48"});
  REQUIRE(r.exit_code == 0);
  const Csv csv = parse_csv(r.out);
  REQUIRE(csv.rows.size() == 49);
  CHECK(number(csv.rows.back()[3]) == Approx(4 * std::acos(-1.0)));
  for (const auto& row : csv.rows) {
    const double t = number(row[0]);
    INFO("t = " << t);
    const auto st = kinegen::closed_form::slider_crank_state(t);
    std::vector<double> expected{t};
    for (int b = 0; b < 2; ++b) {
      for (int c = 0; c < 3; ++c) expected.push_back(st.q[3 * b + c]);
      for (int c = 0; c < 3; ++c) expected.push_back(st.qd[3 * b + c]);
      for (int c = 0; c < 3; ++c) expected.push_back(st.qdd[3 * b + c]);
    }
    // Points: tip = crank [1, 0], slider = rod [0, 0].
    for (const auto& p : {kinegen::closed_form::point_state(st, 0, 1, 0),
                          kinegen::closed_form::point_state(st, 1, 0, 0)})
      for (const auto* v : {&p.r, &p.v, &p.a})
        expected.insert(expected.end(), v->begin(), v->end());
    REQUIRE(row.size() == expected.size());
    for (std::size_t c = 0; c < row.size(); ++c) {
      INFO("column " << csv.header[c]);
      CHECK(number(row[c]) == Approx(expected[c]).margin(1e-9));
    }
  }
}

TEST_CASE("analyze with --steps 0 writes the single row at T0", "[cli]") {
  const auto r = kinegen(
      {"analyze", example("four_bar").string(), "--t0", "0.25", "--t1", "9", "--steps", "0"});
  REQUIRE(r.exit_code == 0);
  const Csv csv = parse_csv(r.out);
  REQUIRE(csv.rows.size() == 1);
  CHECK(number(csv.rows[0][0]) == 0.25);
}

TEST_CASE("analyze -o FILE writes exactly what standard output gets", "[cli]") {
  const fs::path dir = scratch_dir("analyze_output");
  const fs::path csv = dir / "out.csv";
  const std::vector<std::string> args{
      "analyze", example("offset_slider_crank").string(), "--t0", "0", "--t1", "2", "--steps", "8"};
  const auto to_stdout = kinegen(args);
  auto with_file = args;
  with_file.insert(with_file.end(), {"-o", csv.string()});
  const auto to_file = kinegen(with_file);
  REQUIRE(to_stdout.exit_code == 0);
  REQUIRE(to_file.exit_code == 0);
  CHECK(to_file.out.empty());
  CHECK(read_text(csv) == to_stdout.out);
  CHECK(parse_csv(to_stdout.out).rows.size() == 9);
  CHECK(entries(dir) == std::vector<std::string>{"out.csv"});  // no temporary left beside it
}

TEST_CASE("analyze refuses a mechanism with too few equations, and fails on contradictory ones",
          "[cli]") {
  const fs::path dir = scratch_dir("analyze_not_driven");
  const fs::path under = dir / "under_driven.yaml";
  write_text(under, kUnderDriven);
  const fs::path over = dir / "over_driven.yaml";
  write_text(over, std::string(kUnderDriven) +
                       "drivers:\n"
                       "  - type: absolute_angle\n    body: crank\n    f: \"t\"\n"
                       "  - type: absolute_x\n    body: rod\n    f: \"3 - t\"\n");
  const fs::path csv = dir / "out.csv";

  {
    const auto r = kinegen(
        {"analyze", under.string(), "--t0", "0", "--t1", "1", "--steps", "2", "-o", csv.string()});
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.err.find(under.string()) != std::string::npos);
    CHECK(r.out.empty());
    CHECK_FALSE(fs::exists(csv));  // bad input writes no output file at all
  }
  CHECK(entries(dir) == std::vector<std::string>{"over_driven.yaml", "under_driven.yaml"});
  // Seven equations for six coordinates agree at t = 0 (crank at 0, slider at 3): redundant,
  // solved with a warning; from there on the two drivers contradict each other (exit 1, the
  // row at t = 0 kept; docs/stability.md). The step to 0.5 is taken in sub-steps, down to
  // 1/4096 of it, which fail from the first: the analysis names that time.
  const auto r = kinegen(
      {"analyze", over.string(), "--t0", "0", "--t1", "1", "--steps", "2", "-o", csv.string()});
  CHECK(r.exit_code == 1);
  INFO(r.err);
  CHECK(r.err.rfind("warning: " + over.string() + ": redundant constraints", 0) == 0);
  CHECK(r.err.find("\nerror: " + over.string() +
                   ": position analysis failed at t = 0.0001220703125 (in sub-steps of the step "
                   "from t = 0 to t = 0.5") != std::string::npos);
  CHECK(r.err.find("not satisfied") != std::string::npos);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 2);
  CHECK(parse_csv(read_text(csv)).rows.size() == 1);
}

TEST_CASE("analyze on bad input leaves an existing output file untouched", "[cli]") {
  const fs::path dir = scratch_dir("analyze_keeps_existing");
  const fs::path mech = dir / "under_driven.yaml";
  write_text(mech, kUnderDriven);
  const fs::path csv = dir / "out.csv";
  write_text(csv, "previous results\n");
  const auto r = kinegen(
      {"analyze", mech.string(), "--t0", "0", "--t1", "1", "--steps", "2", "-o", csv.string()});
  CHECK(r.exit_code == 2);
  require_one_error_line(r);
  CHECK(read_text(csv) == "previous results\n");
  CHECK(entries(dir) == std::vector<std::string>{"out.csv", "under_driven.yaml"});
}

TEST_CASE("analyze names the file and YAML line of a bad expression and writes nothing", "[cli]") {
  const fs::path dir = scratch_dir("analyze_bad_expression");
  const fs::path mech = dir / "reach.yaml";
  write_text(mech, replaced(kReach, "\"0.3*t\"", "\"0.3*tt\""));  // unknown symbol, line 15
  const fs::path csv = dir / "out.csv";
  const auto r = kinegen(
      {"analyze", mech.string(), "--t0", "0", "--t1", "1", "--steps", "2", "-o", csv.string()});
  CHECK(r.exit_code == 2);
  require_one_error_line(r);
  CHECK(r.err.find(mech.string() + ":15") != std::string::npos);
  CHECK(r.err.find("drivers[0]") != std::string::npos);
  CHECK_FALSE(fs::exists(csv));
}

TEST_CASE("analyze keeps the rows solved before the mechanism fails to assemble", "[cli]") {
  const fs::path dir = scratch_dir("analyze_cannot_assemble");
  const fs::path mech = dir / "reach.yaml";
  write_text(mech, kReach);
  const fs::path csv = dir / "out.csv";

  SECTION("to a file") {
    const auto r = kinegen(
        {"analyze", mech.string(), "--t0", "0", "--t1", "4", "--steps", "4", "-o", csv.string()});
    CHECK(r.exit_code == 1);
    require_one_error_line(r);
    CHECK(r.err.find(mech.string()) != std::string::npos);
    // The tip cannot follow x = 0.3 t past t = 10/3: the sub-steps of the step from 3 to 4
    // stop there, within 1/4096 of it.
    CHECK(time_in_message(r.err) >= 10.0 / 3 - 1.0 / 4096);
    CHECK(time_in_message(r.err) <= 10.0 / 3 + 1.0 / 4096);
    const Csv kept = parse_csv(read_text(csv));
    REQUIRE(kept.rows.size() == 4);  // t = 0, 1, 2, 3
    CHECK(number(kept.rows.back()[0]) == 3.0);
    // The kept rows are real solutions: the tip's x is 0.3 t, i.e. cos(phi) = 0.3 t.
    for (const auto& row : kept.rows)
      CHECK(std::cos(number(row[3])) == Approx(0.3 * number(row[0])).margin(1e-12));
    CHECK(entries(dir) == std::vector<std::string>{"out.csv", "reach.yaml"});
  }
  SECTION("to standard output") {
    const auto r = kinegen({"analyze", mech.string(), "--t0", "0", "--t1", "4", "--steps", "4"});
    CHECK(r.exit_code == 1);
    require_one_error_line(r);
    CHECK(parse_csv(r.out).rows.size() == 4);
  }
}

TEST_CASE("analyze of a slider-crank whose rod is too short fails where it stops reaching",
          "[cli]") {
  // With l = 0.5 the rod reaches the slider line while sin(omega t) <= l, i.e. t <= pi/6:
  // on t = 0, 0.1, ..., 1 the rows up to t = 0.5 are solved, and the sub-steps towards
  // t = 0.6 stop at pi/6, within 1/4096 of the step.
  const fs::path dir = scratch_dir("analyze_short_rod");
  const fs::path csv = dir / "out.csv";
  const auto r = kinegen({"analyze", example("slider_crank").string(), "--t0", "0", "--t1", "1",
                          "--steps", "10", "--param", "l=0.5", "-o", csv.string()});
  CHECK(r.exit_code == 1);
  require_one_error_line(r);
  CHECK(r.err.find(example("slider_crank").string()) != std::string::npos);
  const double failed_at = time_in_message(r.err);
  CHECK(failed_at >= std::asin(0.5) - 0.1 / 4096);
  CHECK(failed_at <= std::asin(0.5) + 0.1 / 4096);
  const Csv kept = parse_csv(read_text(csv));
  CHECK(kept.rows.size() == 6);
  REQUIRE(!kept.rows.empty());
  CHECK(number(kept.rows.back()[0]) < failed_at);
  CHECK(number(kept.rows.back()[0]) == Approx(0.5));
}

TEST_CASE("an error about input text with a line break is still one line", "[cli]") {
  // Known to fail: messages quote the offending text verbatim, line breaks included.
  const fs::path dir = scratch_dir("error_one_line");
  const fs::path mech = dir / "reach.yaml";
  SECTION("an expression written as a YAML block scalar") {
    // `|` keeps the line break after the expression: the text is "0.3*tt\n".
    write_text(mech, replaced(kReach, "f: \"0.3*t\"", "f: |\n      0.3*tt"));
  }
  SECTION("a body name with an escaped line break") {
    write_text(mech, replaced(kReach, "- name: bar", "- name: \"bar\\nbaz\""));
  }
  const auto r = kinegen({"eval", mech.string()});
  CHECK(r.exit_code == 2);
  require_one_error_line(r);
}

// ---------------------------------------------------------------------------------------------
// eval

TEST_CASE("eval prints Phi, Phi_q, nu and gamma at q0 as the in-process evaluator computes",
          "[cli]") {
  for (const auto& name : kExamples) {
    INFO(name);
    const auto r = kinegen({"eval", example(name).string()});
    INFO("stderr: " << r.err);
    REQUIRE(r.exit_code == 0);
    const EvalOutput e = parse_eval(r.out);

    const auto model = kc::CompiledModel::from_file(example(name).string());
    const int nq = model->nq(), nc = model->nc();
    kc::ModelEvaluator<double> eval(*model);
    const Eigen::VectorXd q = model->q0(), qd = Eigen::VectorXd::Zero(nq);
    std::vector<double> phi(nc), nu(nc), gamma(nc);
    Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(nc, nq);
    eval.phi(q.data(), 0.0, phi.data());
    eval.nu(q.data(), 0.0, nu.data());
    eval.gamma(q.data(), qd.data(), 0.0, gamma.data());
    eval.jacobian(q.data(), 0.0, jac);

    require_close(e.phi, phi);
    require_close(e.nu, nu);
    require_close(e.gamma, gamma);
    REQUIRE(e.phi_q.size() == static_cast<std::size_t>(nc));
    for (int row = 0; row < nc; ++row) {
      const Eigen::VectorXd jr = jac.row(row).transpose();
      require_close(e.phi_q[row], std::vector<double>(jr.data(), jr.data() + nq));
    }
  }
}

TEST_CASE("eval honours --t, --q, --qd and --param (slider-crank in closed form)", "[cli]") {
  // Phi = [x1; y1; x1 - x2 + cos p1 + l sin p2; y1 - y2 + sin p1 - l cos p2; y2; p1 - omega t]
  // with q = [x1, y1, p1, x2, y2, p2] (examples/slider_crank.yaml).
  const double x1 = 0.1, y1 = -0.2, p1 = 0.7, x2 = 2.5, y2 = 0.3, p2 = 1.2;
  const double v[6] = {0.5, -1.5, 2.0, 0.25, -0.75, -1.25};
  const double t = 0.75, l = 3.0, omega = 1.0;
  const auto r = kinegen({"eval", example("slider_crank").string(), "--t", "0.75", "--q",
                          "0.1,-0.2,0.7,2.5,0.3,1.2", "--qd", "0.5,-1.5,2.0,0.25,-0.75,-1.25",
                          "--param", "l=3"});
  INFO("stderr: " << r.err);
  REQUIRE(r.exit_code == 0);
  const EvalOutput e = parse_eval(r.out);
  require_close(e.phi, {x1, y1, x1 - x2 + std::cos(p1) + l * std::sin(p2),
                        y1 - y2 + std::sin(p1) - l * std::cos(p2), y2, p1 - omega * t});
  const std::vector<std::vector<double>> jac = {{1, 0, 0, 0, 0, 0},
                                                {0, 1, 0, 0, 0, 0},
                                                {1, 0, -std::sin(p1), -1, 0, l * std::cos(p2)},
                                                {0, 1, std::cos(p1), 0, -1, l * std::sin(p2)},
                                                {0, 0, 0, 0, 1, 0},
                                                {0, 0, 1, 0, 0, 0}};
  REQUIRE(e.phi_q.size() == jac.size());
  for (std::size_t row = 0; row < jac.size(); ++row) require_close(e.phi_q[row], jac[row]);
  require_close(e.nu, {0, 0, 0, 0, 0, omega});
  // gamma = -(Phi_q qd)_q qd: only the rod-crank rows are nonlinear.
  require_close(e.gamma,
                {0, 0, std::cos(p1) * v[2] * v[2] + l * std::sin(p2) * v[5] * v[5],
                 std::sin(p1) * v[2] * v[2] - l * std::cos(p2) * v[5] * v[5], 0, 0},
                1e-13);
}

TEST_CASE("eval defaults to t = 0 and zero velocities", "[cli]") {
  // With qd = 0 the slider-crank's gamma vanishes, and Phi's driver row is phi1(q0) - 0.
  const auto r = kinegen({"eval", example("slider_crank").string(), "--q", "0,0,0.5,2,0,1"});
  REQUIRE(r.exit_code == 0);
  const EvalOutput e = parse_eval(r.out);
  REQUIRE(e.phi.size() == 6);
  CHECK(e.phi[5] == Approx(0.5));
  require_close(e.gamma, std::vector<double>(6, 0.0));
}

TEST_CASE("eval rejects a --q or --qd of the wrong length", "[cli]") {
  for (const std::string option : {"--q", "--qd"}) {
    INFO(option);
    const auto r = kinegen({"eval", example("slider_crank").string(), option, "1,2"});
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.err.find(option) != std::string::npos);
    CHECK(r.out.empty());
  }
}

TEST_CASE("eval names the mechanism file when --q has the wrong length", "[cli]") {
  // Every error names the file. Known to fail: the message names only --q.
  const auto r = kinegen({"eval", example("slider_crank").string(), "--q", "1,2"});
  CHECK(r.exit_code == 2);
  CHECK(r.err.find(example("slider_crank").string()) != std::string::npos);
}

TEST_CASE("generate and eval accept a mechanism with fewer equations than coordinates", "[cli]") {
  const fs::path dir = scratch_dir("under_driven_accepted");
  const fs::path mech = dir / "under_driven.yaml";
  write_text(mech, kUnderDriven);
  const auto e = kinegen({"eval", mech.string()});
  INFO("stderr: " << e.err);
  REQUIRE(e.exit_code == 0);
  const EvalOutput out = parse_eval(e.out);
  CHECK(out.phi.size() == 5);
  REQUIRE(out.phi_q.size() == 5);
  CHECK(out.phi_q[0].size() == 6);

  const auto g = kinegen({"generate", mech.string(), "-o", (dir / "out").string()});
  CHECK(g.exit_code == 0);
  CHECK(entries(dir / "out") == std::vector<std::string>{"under_driven.hpp"});
}

// ---------------------------------------------------------------------------------------------
// generate

// The default of a member of the generated Params struct, as written in the header.
double params_default(const std::string& header, const std::string& member) {
  const auto begin = header.find("struct Params");
  REQUIRE(begin != std::string::npos);
  const std::string params = header.substr(begin, header.find("};", begin) - begin);
  std::smatch match;
  const std::regex member_re("double\\s+" + member + "\\s*=\\s*([^;]+);");
  INFO(params);
  REQUIRE(std::regex_search(params, match, member_re));
  return number(match[1]);
}

TEST_CASE("generate writes DIR/<name>.hpp and nothing else", "[cli]") {
  const fs::path dir = scratch_dir("generate");
  const auto r = kinegen({"generate", example("four_bar").string(), "-o", dir.string()});
  INFO("stderr: " << r.err);
  REQUIRE(r.exit_code == 0);
  CHECK(entries(dir) == std::vector<std::string>{"four_bar.hpp"});
  const std::string header = read_text(dir / "four_bar.hpp");
  CHECK(header.find("namespace kinegen::models") != std::string::npos);
  CHECK(header.find("struct four_bar") != std::string::npos);
  CHECK(params_default(header, "b") == 3.5);
  CHECK(params_default(header, "omega") == 1.0);
}

TEST_CASE("generate writes into the current directory by default", "[cli]") {
  const fs::path dir = scratch_dir("generate_cwd");
  const auto r = kinegen({"generate", example("quick_return").string()}, dir.string());
  REQUIRE(r.exit_code == 0);
  CHECK(entries(dir) == std::vector<std::string>{"quick_return.hpp"});
}

TEST_CASE("generate --param NAME=VALUE changes that parameter's default only", "[cli]") {
  const fs::path dir = scratch_dir("generate_param");
  const auto r = kinegen({"generate", example("slider_crank").string(), "-o", dir.string(),
                          "--param", "l=2.5", "--param", "omega=1/3"});
  INFO("stderr: " << r.err);
  REQUIRE(r.exit_code == 0);
  CHECK(entries(dir) == std::vector<std::string>{"slider_crank.hpp"});
  const std::string header = read_text(dir / "slider_crank.hpp");
  CHECK(params_default(header, "l") == 2.5);
  CHECK(params_default(header, "omega") == 1.0 / 3.0);

  // Without overrides the file's values come back.
  const auto plain = kinegen({"generate", example("slider_crank").string(), "-o", dir.string()});
  REQUIRE(plain.exit_code == 0);
  const std::string regenerated = read_text(dir / "slider_crank.hpp");
  CHECK(params_default(regenerated, "l") == 2.0);
  CHECK(params_default(regenerated, "omega") == 1.0);
}

TEST_CASE("--param with an unknown name or a malformed value is invalid input", "[cli]") {
  const fs::path dir = scratch_dir("param_invalid");
  const std::string mech = example("slider_crank").string();
  const fs::path out = dir / "out";
  const std::vector<std::vector<std::string>> commands = {
      {"generate", mech, "-o", out.string(), "--param", "length=2"},
      {"analyze", mech, "--t0", "0", "--t1", "1", "--steps", "2", "-o", (dir / "out.csv").string(),
       "--param", "length=2"},
      {"eval", mech, "--param", "length=2"},
      {"check", mech, "--param", "length=2"},
      {"generate", mech, "-o", out.string(), "--param", "l=abc"},
      {"generate", mech, "-o", out.string(), "--param", "l"},
  };
  for (const auto& args : commands) {
    INFO(args[0] << " " << args.back());
    const auto r = kinegen(args);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.out.empty());
  }
  // The unknown name is named, and the file with it.
  const auto r = kinegen(commands[0]);
  CHECK(r.err.find("length") != std::string::npos);
  CHECK(r.err.find(mech) != std::string::npos);
  CHECK(entries(dir).empty());
}

TEST_CASE("generate on invalid input writes no header", "[cli]") {
  const fs::path dir = scratch_dir("generate_invalid");
  const fs::path mech = dir / "reach.yaml";
  write_text(mech, replaced(kReach, "q0: [0, 0, 1.5]", "q0: [0, 0]"));  // q0 is on line 4
  const auto r = kinegen({"generate", mech.string(), "-o", (dir / "out").string()});
  CHECK(r.exit_code == 2);
  require_one_error_line(r);
  CHECK(r.err.find(mech.string() + ":4") != std::string::npos);
  CHECK_FALSE(fs::exists(dir / "out" / "reach.hpp"));
  CHECK(entries(dir) == std::vector<std::string>{"reach.yaml"});
}

// ---------------------------------------------------------------------------------------------
// Usage errors and check

TEST_CASE("usage errors exit 2 with one error line", "[cli]") {
  const std::string mech = example("slider_crank").string();
  const std::vector<std::vector<std::string>> commands = {
      {},
      {"frobnicate", mech},
      {"analyze", mech, "--t1", "1", "--steps", "2"},  // --t0 missing
      {"analyze", mech, "--t0", "0", "--t1", "1"},     // --steps missing
      {"analyze", mech, "--t0", "0", "--t1", "1", "--steps", "many"},
      {"analyze", mech, "--t0", "0", "--t1", "1", "--steps", "-1"},
      {"analyze", "--t0", "0", "--t1", "1", "--steps", "2"},  // no mechanism
      {"eval", mech, "--q", "1,2,x,4,5,6"},
      {"generate", mech, "--bogus"},
  };
  for (const auto& args : commands) {
    std::string line;
    for (const auto& a : args) line += a + " ";
    INFO("kinegen " << line);
    const auto r = kinegen(args);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
  }
}

TEST_CASE("a mechanism file that does not exist is invalid input naming the file", "[cli]") {
  const std::string missing = (fs::path(KINEGEN_TEST_TMP) / "no_such_mechanism.yaml").string();
  for (const std::string command : {"generate", "eval", "check"}) {
    INFO(command);
    const auto r = kinegen({command, missing});
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.err.find(missing) != std::string::npos);
  }
}

TEST_CASE("check passes on every example and every test mechanism", "[cli]") {
  std::vector<fs::path> files = yaml_files(fs::path(KINEGEN_SOURCE_DIR) / "examples");
  const auto tests = yaml_files(fs::path(KINEGEN_SOURCE_DIR) / "tests" / "mechanisms");
  files.insert(files.end(), tests.begin(), tests.end());
  REQUIRE(files.size() >= kExamples.size() + 1);  // the examples and all_types.yaml
  for (const auto& file : files) {
    INFO(file.string());
    const auto r = kinegen({"check", file.string()});
    INFO(r.out << r.err);
    CHECK(r.exit_code == 0);
    CHECK(r.err.find("error") == std::string::npos);
  }
}

}  // namespace
