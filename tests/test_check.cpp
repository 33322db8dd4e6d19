// `kinegen check`: its three methods accept every example (also after many turns), and reject
// deliberately wrong Phi_q and gamma in the right block; the CLI's table, exit codes and the
// --reference-digits option of analyze.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/check.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "support/cli.hpp"

namespace {

namespace cg = kinegen::codegen;
namespace fs = std::filesystem;

std::vector<std::string> example_files() {
  std::vector<std::string> f;
  for (const auto& e : fs::directory_iterator(fs::path(KINEGEN_SOURCE_DIR) / "examples"))
    if (e.path().extension() == ".yaml") f.push_back(e.path().string());
  std::sort(f.begin(), f.end());
  return f;
}

using kinegen::test::kinegen_cli;

std::string describe(const std::vector<cg::CheckRow>& rows) {
  std::ostringstream os;
  for (const auto& r : rows)
    os << r.block << " " << r.method << " rel " << r.max_rel << " bound " << r.bound
       << (r.ok() ? " ok" : " FAILED") << "\n";
  return os.str();
}

const cg::CheckRow& row(const std::vector<cg::CheckRow>& rows, const std::string& block,
                        const std::string& method) {
  for (const auto& r : rows)
    if (r.block == block && r.method.rfind(method, 0) == 0) return r;
  FAIL("no row " << block << " " << method);
  return rows.front();
}

const std::vector<std::string> kMethods = {"complex-step", "central-difference", "cln-"};

// The structural non-zero of Phi_q that depends on q (so its error moves with the sample).
int varying_entry(const cg::CompiledModel& model) {
  const auto& entries = model.symbolic().phi_q;
  for (std::size_t e = 0; e < entries.size(); ++e)
    for (int k = 0; k < model.nq(); ++k)
      if (entries[e].value.has(model.symbols().q(k))) return static_cast<int>(e);
  FAIL("no varying entry");
  return -1;
}

}  // namespace

TEST_CASE("check accepts every example with all three methods", "[check]") {
  for (const auto& file : example_files()) {
    INFO(file);
    const auto model = cg::CompiledModel::from_file(file);
    cg::CheckOptions options;
    options.samples = 10;
    const auto rows = cg::check_derivatives(*model, options);
    INFO(describe(rows));
    REQUIRE(rows.size() == 9);
    for (const auto& r : rows) CHECK(r.ok());
    CHECK(row(rows, "phi_q", "cln-").method == "cln-40");
  }
}

TEST_CASE("check stays right with angles grown to 1e4 rad", "[check]") {
  for (const auto& file : example_files()) {
    INFO(file);
    const auto model = cg::CompiledModel::from_file(file);
    cg::CheckOptions options;
    options.samples = 10;
    options.turns = 1600;  // 2 pi 1600 = 1.0e4 rad
    const auto rows = cg::check_derivatives(*model, options);
    INFO(describe(rows));
    for (const auto& r : rows) CHECK(r.ok());
    // The differences are still found: the angles moved, the derivatives did not get worse.
    CHECK(row(rows, "phi_q", "complex-step").max_rel < 1e-15);
    CHECK(row(rows, "phi_q", "cln-").max_rel < 1e-15);
  }
}

TEST_CASE("check rejects a wrong Jacobian entry in phi_q only, by every method", "[check]") {
  const auto model =
      cg::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/examples/four_bar.yaml");
  const int wrong = varying_entry(*model);
  cg::ModelEvaluator<double> eval(*model);
  cg::CheckOptions options;
  options.samples = 5;
  options.candidate.phi_q_values = [&](const double* q, double t, double* out) {
    eval.phi_q_values(q, t, out);
    out[wrong] = -out[wrong];  // a sign mistake in one entry
  };
  const auto rows = cg::check_derivatives(*model, options);
  INFO(describe(rows));
  for (const auto& m : kMethods) {
    CHECK_FALSE(row(rows, "phi_q", m).ok());
    CHECK(row(rows, "nu", m).ok());
    CHECK(row(rows, "gamma", m).ok());
  }
}

TEST_CASE("a Jacobian wrong by 1e-9 relative escapes differences, not complex step or CLN",
          "[check]") {
  const auto model =
      cg::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/examples/four_bar.yaml");
  const int wrong = varying_entry(*model);
  cg::ModelEvaluator<double> eval(*model);
  cg::CheckOptions options;
  options.candidate.phi_q_values = [&](const double* q, double t, double* out) {
    eval.phi_q_values(q, t, out);
    out[wrong] *= 1 + 1e-9;
  };
  const auto rows = cg::check_derivatives(*model, options);
  INFO(describe(rows));
  CHECK_FALSE(row(rows, "phi_q", "complex-step").ok());
  CHECK_FALSE(row(rows, "phi_q", "cln-").ok());
  CHECK(row(rows, "phi_q", "central-difference").ok());
}

TEST_CASE("check rejects a wrong gamma in gamma only, by every method", "[check]") {
  const auto model =
      cg::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/examples/quick_return.yaml");
  cg::ModelEvaluator<double> eval(*model);
  cg::CheckOptions options;
  options.candidate.gamma = [&](const double* q, const double* qd, double t, double* out) {
    eval.gamma(q, qd, t, out);
    // A slip in one row: its largest entry halved.
    int big = 0;
    for (int r = 1; r < model->nc(); ++r)
      if (std::abs(out[r]) > std::abs(out[big])) big = r;
    out[big] *= 0.5;
  };
  const auto rows = cg::check_derivatives(*model, options);
  INFO(describe(rows));
  for (const auto& m : kMethods) {
    CHECK(row(rows, "phi_q", m).ok());
    CHECK(row(rows, "nu", m).ok());
    CHECK_FALSE(row(rows, "gamma", m).ok());
  }
}

TEST_CASE("check options are validated", "[check]") {
  const auto model =
      cg::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/examples/four_bar.yaml");
  cg::CheckOptions options;
  options.digits = 10;
  CHECK_THROWS_AS(cg::check_derivatives(*model, options), cg::UsageError);
  options = {};
  options.samples = 0;
  CHECK_THROWS_AS(cg::check_derivatives(*model, options), cg::UsageError);
}

TEST_CASE("check CLI: table with all methods, exit 0 on every example, --turns, --structure",
          "[check][cli]") {
  for (const auto& file : example_files()) {
    INFO(file);
    const auto r = kinegen_cli({"check", file, "--samples", "8", "--seed", "7"});
    INFO(r.out << r.err);
    CHECK(r.exit_code == 0);
    for (const std::string block : {"phi_q ", "nu ", "gamma "})
      CHECK(r.out.find("\n" + block) != std::string::npos);
    CHECK(r.out.find("cln-40") != std::string::npos);
    CHECK(r.out.find("central-difference") != std::string::npos);
    CHECK(r.out.find("complex-step") != std::string::npos);
    CHECK(r.out.find("FAILED") == std::string::npos);
  }
  const std::string four_bar = std::string(KINEGEN_SOURCE_DIR) + "/examples/four_bar.yaml";
  const auto turned = kinegen_cli({"check", four_bar, "--turns", "1600"});
  INFO(turned.out << turned.err);
  CHECK(turned.exit_code == 0);
  const auto structure = kinegen_cli({"check", four_bar, "--structure"});
  CHECK(structure.exit_code == 0);
  CHECK(structure.out.find("Phi_q structure (9 x 9, 19 structural non-zeros") != std::string::npos);
  CHECK(structure.out.find("13 constant, 6 varying") != std::string::npos);
  const auto bad = kinegen_cli({"check", four_bar, "--digits", "5"});
  CHECK(bad.exit_code == 2);
  CHECK(bad.err.rfind("error: ", 0) == 0);
}

TEST_CASE("analyze --reference-digits: same columns, values at rounding level, exit codes",
          "[check][cli][reference]") {
  const std::string four_bar = std::string(KINEGEN_SOURCE_DIR) + "/examples/four_bar.yaml";
  fs::create_directories(KINEGEN_TEST_TMP);
  const std::string ref_csv = std::string(KINEGEN_TEST_TMP) + "/four_bar_ref40.csv";
  const std::string dbl_csv = std::string(KINEGEN_TEST_TMP) + "/four_bar_double.csv";
  const std::vector<std::string> grid = {"--t0", "0", "--t1", "6.283185307179586", "--steps", "36"};
  auto args = std::vector<std::string>{"analyze", four_bar};
  args.insert(args.end(), grid.begin(), grid.end());
  auto ref_args = args, dbl_args = args;
  ref_args.insert(ref_args.end(), {"--reference-digits", "40", "-o", ref_csv});
  dbl_args.insert(dbl_args.end(), {"-o", dbl_csv});
  const auto ref = kinegen_cli(ref_args);
  const auto dbl = kinegen_cli(dbl_args);
  INFO(ref.err << dbl.err);
  REQUIRE(ref.exit_code == 0);
  REQUIRE(dbl.exit_code == 0);
  std::ifstream a(ref_csv), b(dbl_csv);
  std::string la, lb;
  std::getline(a, la);
  std::getline(b, lb);
  CHECK(la == lb);  // the same columns
  int rows = 0;
  double worst = 0;
  while (std::getline(a, la) && std::getline(b, lb)) {
    std::stringstream sa(la), sb(lb);
    std::string xa, xb;
    while (std::getline(sa, xa, ',') && std::getline(sb, xb, ','))
      worst = std::max(worst, std::abs(std::stod(xa) - std::stod(xb)));
    ++rows;
  }
  CHECK(rows == 37);
  CHECK(worst < 1e-13);
  CHECK(worst > 0);  // two different computations, not one copied

  auto bad_args = args;
  const std::string bad_csv = std::string(KINEGEN_TEST_TMP) + "/four_bar_ref_bad.csv";
  fs::remove(bad_csv);
  bad_args.insert(bad_args.end(), {"--reference-digits", "12", "-o", bad_csv});
  const auto bad = kinegen_cli(bad_args);
  CHECK(bad.exit_code == 2);
  CHECK(bad.err.rfind("error: ", 0) == 0);
  CHECK_FALSE(fs::exists(bad_csv));  // no half-written output
}

TEST_CASE("analyze --reference-digits fails like analyze where the mechanism cannot assemble",
          "[check][cli][reference]") {
  const std::string four_bar = std::string(KINEGEN_SOURCE_DIR) + "/examples/four_bar.yaml";
  for (const bool reference : {false, true}) {
    std::vector<std::string> args = {"analyze", four_bar, "--param", "c=0.1",   "--t0",
                                     "0",       "--t1",   "1",       "--steps", "3"};
    if (reference) args.insert(args.end(), {"--reference-digits", "30"});
    const auto r = kinegen_cli(args);
    INFO(reference << ": " << r.err);
    CHECK(r.exit_code == 1);
    CHECK(r.err.rfind("error: ", 0) == 0);
    CHECK(r.err.find("did not converge") != std::string::npos);
    CHECK(r.out.rfind("t,crank.x", 0) == 0);  // the header, no rows
  }
}
