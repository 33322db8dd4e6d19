// One algorithm, two back ends: `kinegen analyze` (run_analysis, the in-process block
// program of block_interpreter.hpp) and a program that steps the generated kinegen::Solver over
// the same grid give the same q, qd and qdd, bit for bit (issue 12). Both run the block program
// with the same kernels; the header's statements are compiled C++ and the interpreter's are
// ProgramEvaluator::node_value and the kernels compiled here, so any difference in an operation's
// order or a kernel's use shows up as a differing bit.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <kinegen/block_solver.hpp>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "big_small.hpp"
#include "cam_flat.hpp"
#include "cam_roller.hpp"
#include "closed_chain_4.hpp"
#include "closed_chain_4_split.hpp"
#include "closed_chain_masses_split.hpp"
#include "crank_gravity.hpp"
#include "disc_cam.hpp"
#include "drag_link.hpp"
#include "dwell_slider_crank.hpp"
#include "far_point.hpp"
#include "four_bar.hpp"
#include "four_bar_balanced.hpp"
#include "fourbar_chain_3_split.hpp"
#include "gear_pair.hpp"
#include "guarded_slider.hpp"
#include "guarded_slider_split.hpp"
#include "harmonic_return.hpp"
#include "indexer.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/block_interpreter.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "offset_slider_crank.hpp"
#include "parabolic_slot.hpp"
#include "planetary.hpp"
#include "press.hpp"
#include "quick_return.hpp"
#include "scissor_lift_3.hpp"
#include "scissor_lift_3_split.hpp"
#include "slider_crank.hpp"
#include "slider_crank_lecture.hpp"
#include "slider_driven.hpp"
#include "slot.hpp"
#include "steering.hpp"
#include "stephenson3.hpp"
#include "table_press.hpp"

namespace {

using kinegen::codegen::CompiledModel;
using kinegen::codegen::StateRow;
using kinegen::codegen::TimeGrid;

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Rows of run_analysis and of Solver::step over `grid`; counts the values whose bits differ.
template <class Model>
void check_same(const std::string& path, const TimeGrid& grid, int* blocks_out = nullptr) {
  INFO(path);
  const auto model = CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/" + path);
  REQUIRE(kinegen::codegen::BlockInterpreter::supported(model->structure()));
  std::vector<StateRow> rows;
  kinegen::codegen::run_analysis(*model, grid, [&](const StateRow& r) { rows.push_back(r); });
  REQUIRE(static_cast<int>(rows.size()) == grid.steps + 1);

  // With analyze's sub-steps, so that a refused step is taken in the same halves on both.
  kinegen::SolverOptions options = kinegen::default_options<double>();
  options.substep_halvings = kinegen::kAnalyzeSubstepHalvings;
  kinegen::Solver<Model> solver(typename Model::Params{}, options);
  typename kinegen::Solver<Model>::Vector q = solver.initial_estimate(), qd, qdd;
  qd.setZero();
  qdd.setZero();
  int differ = 0, compared = 0;
  std::string first;
  for (int k = 0; k <= grid.steps; ++k) {
    const double t = grid.at(k);
    const auto r = solver.step(t, q, qd, qdd);
    INFO("t = " << t << " status " << r.message());
    REQUIRE(r);
    for (int c = 0; c < Model::nq; ++c) {
      const double values[3][2] = {
          {q[c], rows[k].q[c]}, {qd[c], rows[k].qd[c]}, {qdd[c], rows[k].qdd[c]}};
      for (int d = 0; d < 3; ++d) {
        ++compared;
        if (same_bits(values[d][0], values[d][1])) continue;
        if (first.empty())
          first = "row " + std::to_string(k) + " coordinate " + std::to_string(c) + " derivative " +
                  std::to_string(d) + ": " + std::to_string(values[d][0]) + " vs " +
                  std::to_string(values[d][1]);
        ++differ;
      }
    }
  }
  INFO("first difference: " << first);
  CHECK(differ == 0);
  CHECK(compared == 3 * Model::nq * (grid.steps + 1));
  // The dense Newton on all of Phi_q, an independent algorithm, agrees to rounding.
  kinegen::codegen::AnalysisOptions dense;
  dense.block_solver = false;
  std::vector<StateRow> dense_rows;
  kinegen::codegen::run_analysis(*model, grid,
                                 [&](const StateRow& r) { dense_rows.push_back(r); }, dense);
  REQUIRE(dense_rows.size() == rows.size());
  double worst = 0;
  for (std::size_t k = 0; k < rows.size(); ++k)
    for (const auto* pair : {&rows[k].q, &rows[k].qd, &rows[k].qdd}) {
      const Eigen::VectorXd& block_values = *pair;
      const Eigen::VectorXd& dense_values = pair == &rows[k].q    ? dense_rows[k].q
                                            : pair == &rows[k].qd ? dense_rows[k].qd
                                                                  : dense_rows[k].qdd;
      for (int c = 0; c < block_values.size(); ++c)
        worst = std::max(worst, std::abs(block_values[c] - dense_values[c]) /
                                    std::max(1.0, std::abs(dense_values[c])));
    }
  INFO("block vs dense: " << worst);
  CHECK(worst < 1e-9);
  if (blocks_out) *blocks_out = static_cast<int>(model->structure().plans.size());
}

constexpr double kTurn = 6.283185307179586;

// Model::solve_step (the generated kernels, with a sin/cos cache and the blocks' signs kept by
// the caller, as kinegen::Solver keeps them) and BlockInterpreter::solve_step, fed the same
// start at every time: each step's whole report (status, failing block, iterations, step,
// residual, rcond) and q, qd, qdd must agree bit for bit, failed steps included. A step
// starts from the last solved q moved along its qd (the same start for both); a failed step
// is followed by one from the last solution. Returns each step's status.
template <class Model>
std::vector<int> check_same_reports(const CompiledModel& model, const typename Model::Params& p,
                                    const std::vector<double>& times) {
  kinegen::codegen::BlockInterpreter interp(model);
  REQUIRE(static_cast<int>(interp.structure().plans.size()) == Model::num_blocks);
  const typename Model::BlockOptions og;
  const kinegen::codegen::BlockInterpreter::Options oi;
  std::vector<double> trig(std::max(1, Model::trig_cache_size),
                           std::numeric_limits<double>::quiet_NaN());
  std::vector<signed char> signs(Model::num_blocks, 0);
  constexpr int nq = Model::nq;
  double good_q[nq], good_qd[nq] = {};
  for (int c = 0; c < nq; ++c) good_q[c] = Model::q0[c];
  double t_good = times.empty() ? 0 : times[0];
  std::vector<int> statuses;
  int mismatches = 0;
  std::string first;
  for (double t : times) {
    double qg[nq], qdg[nq] = {}, qddg[nq] = {}, qi[nq], qdi[nq] = {}, qddi[nq] = {};
    for (int c = 0; c < nq; ++c) qg[c] = qi[c] = good_q[c] + (t - t_good) * good_qd[c];
    const auto rg = Model::solve_step(qg, t, p, qdg, qddg, og, trig.data(), signs.data());
    const auto ri = interp.solve_step(qi, t, qdi, qddi, oi);
    statuses.push_back(rg.status);
    bool same = rg.status == ri.status && rg.block == ri.block &&
                rg.iterations == ri.iterations && rg.total_iterations == ri.total_iterations &&
                same_bits(rg.step, ri.step) && same_bits(rg.residual, ri.residual) &&
                same_bits(rg.rcond, ri.rcond);
    for (int c = 0; c < nq; ++c) {
      same = same && same_bits(qg[c], qi[c]);
      if (rg.status == 0) same = same && same_bits(qdg[c], qdi[c]) && same_bits(qddg[c], qddi[c]);
    }
    if (!same) {
      ++mismatches;
      if (first.empty())
        first = "t = " + std::to_string(t) + ": status " + std::to_string(rg.status) + " / " +
                std::to_string(ri.status) + ", block " + std::to_string(rg.block) + " / " +
                std::to_string(ri.block) + ", iterations " + std::to_string(rg.iterations) +
                " / " + std::to_string(ri.iterations) + ", rcond " + std::to_string(rg.rcond) +
                " / " + std::to_string(ri.rcond);
    }
    if (rg.status == 0) {
      std::copy(qg, qg + nq, good_q);
      std::copy(qdg, qdg + nq, good_qd);
      t_good = t;
    }
  }
  INFO("first difference: " << first);
  CHECK(mismatches == 0);
  return statuses;
}

std::unique_ptr<CompiledModel> load(const std::string& path,
                                    const std::vector<kinegen::codegen::ParamOverride>& o = {}) {
  return CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/" + path, o);
}

std::vector<double> grid_times(double t0, double t1, int steps) {
  std::vector<double> times;
  for (int k = 0; k <= steps; ++k) times.push_back(TimeGrid{t0, t1, steps}.at(k));
  return times;
}

}  // namespace

TEST_CASE("analyze and the generated Solver give the same bits on every example over a turn",
          "[same_answers]") {
  const TimeGrid turn{0, kTurn, 360};
  check_same<kinegen::models::four_bar>("examples/four_bar.yaml", turn);
  check_same<kinegen::models::slider_crank>("examples/slider_crank.yaml", turn);
  check_same<kinegen::models::slider_crank_lecture>("examples/slider_crank_lecture.yaml", turn);
  check_same<kinegen::models::offset_slider_crank>("examples/offset_slider_crank.yaml", turn);
  check_same<kinegen::models::quick_return>("examples/quick_return.yaml", turn);
  check_same<kinegen::models::four_bar_balanced>("examples/forces/four_bar_balanced.yaml", turn);
  check_same<kinegen::models::press>("examples/forces/press.yaml", turn);
  check_same<kinegen::models::planetary>("examples/gears/planetary.yaml", turn);
  check_same<kinegen::models::steering>("examples/gears/steering.yaml", turn);
  check_same<kinegen::models::disc_cam>("examples/cams/disc_cam.yaml", turn);
  check_same<kinegen::models::slot>("examples/slots/slot.yaml", turn);
  // A periodic measured table (spline kernel) over two periods.
  check_same<kinegen::models::table_press>("examples/forces/table_press.yaml", {0, 2, 240});
}

TEST_CASE("the same bits on torn, guarded and larger blocks", "[same_answers]") {
  const TimeGrid turn{0, kTurn, 200};
  check_same<kinegen::models::closed_chain_4>("tests/mechanisms/closed_chain_4.yaml", turn);
  check_same<kinegen::models::scissor_lift_3>("tests/mechanisms/scissor_lift_3.yaml", {0, 1, 100});
  check_same<kinegen::models::slider_driven>("tests/mechanisms/slider_driven.yaml", {0, 1, 100});
  check_same<kinegen::models::far_point>("tests/mechanisms/far_point.yaml", turn);
  check_same<kinegen::models::big_small>("tests/mechanisms/big_small.yaml", turn);
  check_same<kinegen::models::guarded_slider>("tests/mechanisms/guarded_slider.yaml", {0, 1, 100});
  check_same<kinegen::models::drag_link>("tests/mechanisms/drag_link.yaml", turn);
  check_same<kinegen::models::stephenson3>("tests/mechanisms/stephenson3.yaml", turn);
  check_same<kinegen::models::gear_pair>("tests/mechanisms/gear_pair.yaml", turn);
  check_same<kinegen::models::crank_gravity>("tests/mechanisms/crank_gravity.yaml", turn);
  // Motion laws with dwells (the clamped law kernel).
  check_same<kinegen::models::dwell_slider_crank>("tests/mechanisms/dwell_slider_crank.yaml",
                                                  {0, 5, 200});
  // A coarse grid over a period of the indexer (pieces, harmonic and 3-4-5): steps refused
  // and taken in sub-steps, the same halves on both.
  check_same<kinegen::models::indexer>("tests/mechanisms/indexer.yaml", {0, 4, 4});
  // Laws exactly at their boundaries: a harmonic rise-return repeated.
  check_same<kinegen::models::harmonic_return>("tests/mechanisms/harmonic_return.yaml",
                                               {0, 6, 24});
  // Extra coordinates and curve joints.
  check_same<kinegen::models::cam_flat>("tests/mechanisms/cam_flat.yaml", turn);
  check_same<kinegen::models::cam_roller>("tests/mechanisms/cam_roller.yaml", turn);
  check_same<kinegen::models::parabolic_slot>("tests/mechanisms/parabolic_slot.yaml", {0, 1, 100});
}

TEST_CASE("a guarded block whose coefficient vanishes beside its couplings fails, on both paths",
          "[same_answers][stability]") {
  // guarded_slider.yaml: k x_slider - cos(phi_crank) = 0. With k = 1e-14 the coefficient is
  // 1e-14 beside the row's coupling sin(phi_crank): Phi_q is singular in all but name, and
  // x_slider = cos / k (1e14) is no answer. Not zero, so only the condition check sees it.
  // At t = 0 (sin = 0, no coupling) x_slider = 1 / k assembles; every later step must fail.
  using Model = kinegen::models::guarded_slider;
  Model::Params p;
  p.k = 1e-14;
  kinegen::Solver<Model> solver(p);
  auto q = solver.initial_estimate();
  decltype(q) qd = decltype(q)::Zero(), qdd = decltype(q)::Zero();
  // From the file's q0 (x_slider = 0.5) the first solve would have to move the row's value
  // by 1 through a coefficient of 1e-14: refused with a status, never a wrong answer.
  CHECK(solver.step(0.25, q, qd, qdd).status == kinegen::Status::kTooFar);
  solver.reset();
  q = solver.initial_estimate();
  q[3] = 1e14;  // x_slider where it fits at t = 0
  REQUIRE(solver.step(0, q, qd, qdd));
  const auto r = solver.step(0.25, q, qd, qdd);
  CHECK(r.status == kinegen::Status::kSingular);
  CHECK(r.block >= 0);
  p.k = 2;  // the file's value: solved
  kinegen::Solver<Model> fine(p);
  q = fine.initial_estimate();
  CHECK(fine.step(0.25, q, qd, qdd));

  // analyze from a file whose q0 assembles at t = 0 with k = 1e-14.
  std::ifstream in(std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/guarded_slider.yaml");
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml = text.str();
  const std::string slider_q0 = "q0: [0.5, 0.5, 0]";
  REQUIRE(yaml.find(slider_q0) != std::string::npos);
  yaml.replace(yaml.find(slider_q0), slider_q0.size(), "q0: [1e14, 0.5, 0]");
  std::filesystem::create_directories(KINEGEN_TEST_TMP);
  const std::string file = std::string(KINEGEN_TEST_TMP) + "/guarded_slider_assembled.yaml";
  std::ofstream(file) << yaml;
  const auto model = CompiledModel::from_file(file, {{"k", "1e-14"}});
  // Singular for every t > 0: the step to 0.25 is refused, and so are its sub-steps.
  CHECK_THROWS_WITH(
      kinegen::codegen::run_analysis(*model, {0, 1, 4}, [](const StateRow&) {}),
      Catch::Contains("(in sub-steps of the step from t = 0 to t = 0.25") &&
          Catch::Contains("singular"));
}

TEST_CASE("the same reports, failed steps included: status, block, iterations, rcond",
          "[same_answers]") {
  namespace km = kinegen::models;
  const int kOk = 0, kSingular = 2, kNonFinite = 3;
  const auto count = [](const std::vector<int>& s, int status) {
    return std::count(s.begin(), s.end(), status);
  };
  {
    INFO("four_bar over a turn");
    const auto model = load("examples/four_bar.yaml");
    const auto s = check_same_reports<km::four_bar>(*model, {}, grid_times(0, kTurn, 120));
    CHECK(count(s, kOk) == 121);
  }
  {
    INFO("closed_chain_4 (torn blocks) over a turn");
    const auto model = load("tests/mechanisms/closed_chain_4.yaml");
    const auto s = check_same_reports<km::closed_chain_4>(*model, {}, grid_times(0, kTurn, 120));
    CHECK(count(s, kOk) == 121);
  }
  {
    // The scissor lift driven flat (w0 = l, dw = 0): each stage's angle solves cos = 1, a
    // double root, onto which Newton converges only linearly; the Newton policy calls it
    // singular (the block's condition there is about sqrt(eps)).
    INFO("scissor_lift_3 with its bars flat");
    const auto model = load("tests/mechanisms/scissor_lift_3.yaml", {{"w0", "1"}, {"dw", "0"}});
    km::scissor_lift_3::Params p;
    p.w0 = 1;
    p.dw = 0;
    const auto s = check_same_reports<km::scissor_lift_3>(*model, p, grid_times(0, 1, 4));
    CHECK(count(s, kSingular) == 5);
  }
  {
    // Driven past its reach (w = 0.85 + 0.2 sin t passes w = l = 1, bars flat, at t = 0.848):
    // the steps before it solve, the ones past it fail.
    INFO("scissor_lift_3 driven past its bars flat");
    const auto model = load("tests/mechanisms/scissor_lift_3.yaml", {{"w0", "0.85"}});
    km::scissor_lift_3::Params p;
    p.w0 = 0.85;
    const auto s = check_same_reports<km::scissor_lift_3>(*model, p, grid_times(0, 2, 40));
    CHECK(count(s, kOk) > 10);
    CHECK(count(s, kOk) < 41);
  }
  {
    // A non-finite parameter (embedded code can set one; the command line refuses it): the
    // interpreter reads the model's parameter vector, set here the same way.
    INFO("four_bar with a NaN coupler length");
    const auto model = load("examples/four_bar.yaml");
    const int k = model->symbols().find_param("b");
    REQUIRE(k >= 0);
    const_cast<std::vector<double>&>(model->params())[k] = std::nan("");
    km::four_bar::Params p;
    p.b = std::nan("");
    const auto s = check_same_reports<km::four_bar>(*model, p, grid_times(0, 1, 2));
    CHECK(count(s, kNonFinite) == 3);
  }
  {
    INFO("four_bar at t = NaN");
    const auto model = load("examples/four_bar.yaml");
    const auto s = check_same_reports<km::four_bar>(*model, {},
                                                    {0.0, std::nan(""), 0.1});
    CHECK(s == std::vector<int>{kOk, kNonFinite, kOk});
  }
}

namespace {

// Whether the generated header <name>.hpp of the split test headers (tests/CMakeLists.txt,
// --max-function-ops 8) really has its block solver in parts.
bool split_solver(const std::string& name) {
  std::ifstream in(std::string(KINEGEN_SPLIT_DIR) + "/" + name + ".hpp");
  std::stringstream text;
  text << in.rdbuf();
  return text.str().find("_solve_position_part1(") != std::string::npos &&
         text.str().find("_solve_velocity_acceleration_part1(") != std::string::npos;
}

}  // namespace

// Headers split into parts (kinegen generate --max-function-ops 8) pass the sin and cos of
// every solved coordinate from part to part in _sc, as the whole function keeps them in its
// variables: they give analyze's bits too (Newton chains, torn and guarded blocks, forces).
TEST_CASE("split headers give the same bits as analyze", "[same_answers][split]") {
  namespace km = kinegen::models;
  for (const char* name : {"fourbar_chain_3_split", "scissor_lift_3_split", "closed_chain_4_split",
                           "guarded_slider_split", "closed_chain_masses_split"}) {
    INFO(name);
    CHECK(split_solver(name));
  }
  const TimeGrid turn{0, kTurn, 200};
  check_same<km::fourbar_chain_3_split>("tests/mechanisms/fourbar_chain_3.yaml", turn);
  check_same<km::scissor_lift_3_split>("tests/mechanisms/scissor_lift_3.yaml", {0, 1, 100});
  check_same<km::closed_chain_4_split>("tests/mechanisms/closed_chain_4.yaml", turn);
  check_same<km::guarded_slider_split>("tests/mechanisms/guarded_slider.yaml", {0, 1, 100});
  check_same<km::closed_chain_masses_split>("tests/mechanisms/closed_chain_masses.yaml", turn);
  // Whole reports too, with the cache and the blocks' signs kept from step to step.
  const auto chain = load("tests/mechanisms/fourbar_chain_3.yaml");
  CHECK(check_same_reports<km::fourbar_chain_3_split>(*chain, {}, grid_times(0, kTurn, 120)) ==
        std::vector<int>(121, 0));
  const auto torn = load("tests/mechanisms/closed_chain_4.yaml");
  CHECK(check_same_reports<km::closed_chain_4_split>(*torn, {}, grid_times(0, kTurn, 120)) ==
        std::vector<int>(121, 0));
}
