// The structural decomposition (codegen/structure.hpp) and the generated block solver:
// the BLT order is valid on every example, the classification is the expected one, the block
// solver agrees with the dense solver, float works, guarded explicit rows stay correct, and
// singular blocks are reported.
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <kinegen/solver.hpp>
#include <map>
#include <random>
#include <set>
#include <string>

#include "closed_chain_4.hpp"
#include "four_bar.hpp"
#include "fourbar_chain_3.hpp"
#include "guarded_slider.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "kinegen/codegen/structure/structure.hpp"
#include "offset_slider_crank.hpp"
#include "quick_return.hpp"
#include "scissor_lift_3.hpp"
#include "slider_crank.hpp"
#include "slider_crank_lecture.hpp"

namespace cg = kinegen::codegen;

namespace {

std::unique_ptr<cg::CompiledModel> load(const std::string& name) {
  return cg::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/examples/" + name +
                                      ".yaml");
}

// Every row and column in exactly one block, square blocks, and each row touching only its own
// block's or earlier blocks' columns.
void check_blt(const cg::BltOrder& order, int n, const std::vector<int>& rows,
               const std::vector<int>& cols) {
  REQUIRE(order.perfect);
  std::vector<int> row_seen(n, 0), col_seen(n, 0);
  for (std::size_t b = 0; b < order.blocks.size(); ++b) {
    const auto& blk = order.blocks[b];
    REQUIRE(!blk.rows.empty());
    REQUIRE(blk.rows.size() == blk.cols.size());
    for (int r : blk.rows) {
      ++row_seen[r];
      CHECK(order.row_block[r] == static_cast<int>(b));
    }
    for (int c : blk.cols) {
      ++col_seen[c];
      CHECK(order.col_block[c] == static_cast<int>(b));
    }
  }
  for (int k = 0; k < n; ++k) {
    CHECK(row_seen[k] == 1);
    CHECK(col_seen[k] == 1);
  }
  for (std::size_t e = 0; e < rows.size(); ++e)
    CHECK(order.col_block[cols[e]] <= order.row_block[rows[e]]);
}

}  // namespace

TEST_CASE("BLT order of every example is valid and classified", "[structure]") {
  struct Expect {
    const char* name;
    int blocks, newton, largest;
  };
  // Newton blocks: the rod angle (slider-cranks, the lecture's rod and slider), the coupler and
  // rocker angles together (four-bar), the rocker angle (quick-return).
  const Expect expects[] = {{"slider_crank", 6, 1, 1},
                            {"offset_slider_crank", 9, 1, 1},
                            {"four_bar", 8, 1, 2},
                            {"quick_return", 9, 1, 1}};
  for (const auto& x : expects) {
    INFO(x.name);
    const auto model = load(x.name);
    const cg::Structure st = cg::analyze_structure(model->symbolic(), model->symbols());
    const auto& p = model->programs();
    check_blt(st.order, model->nq(), p.jac_rows, p.jac_cols);
    CHECK(static_cast<int>(st.plans.size()) == x.blocks);
    CHECK(st.newton_count() == x.newton);
    CHECK(st.largest_block() == x.largest);
    // Every explicit block is one equation linear in its coordinate.
    for (const auto& plan : st.plans)
      if (plan.kind != cg::BlockKind::kNewton) CHECK(plan.block.rows.size() == 1);
  }
  // The lecture's slider-crank: the structure must be a valid BLT whatever its split.
  const auto lecture = load("slider_crank_lecture");
  const cg::Structure st = cg::analyze_structure(lecture->symbolic(), lecture->symbols());
  check_blt(st.order, lecture->nq(), lecture->programs().jac_rows, lecture->programs().jac_cols);
  // The generated headers carry the same classification.
  CHECK(kinegen::models::four_bar::num_blocks == 8);
  CHECK(kinegen::models::four_bar::max_block_size == 2);
  CHECK(kinegen::models::slider_crank::num_explicit_blocks == 5);
}

TEST_CASE("blt_order: cycles, chains, structural singularity, large sizes", "[structure]") {
  SECTION("a cycle is one block") {
    // r0: c0 c1, r1: c1 c2, r2: c2 c0 -> one 3 x 3 block
    const std::vector<int> rows = {0, 0, 1, 1, 2, 2}, cols = {0, 1, 1, 2, 2, 0};
    const auto order = cg::blt_order(3, 3, rows, cols);
    check_blt(order, 3, rows, cols);
    CHECK(order.blocks.size() == 1);
  }
  SECTION("a triangular chain is all 1 x 1, in dependency order") {
    const int n = 3000;  // and no recursion: a deep chain
    std::vector<int> rows, cols;
    for (int r = 0; r < n; ++r) {
      const int c = n - 1 - r;  // row r solves column n-1-r and reads the column after it
      rows.push_back(r);
      cols.push_back(c);
      if (c + 1 < n) {
        rows.push_back(r);
        cols.push_back(c + 1);
      }
    }
    const auto order = cg::blt_order(n, n, rows, cols);
    check_blt(order, n, rows, cols);
    CHECK(order.blocks.size() == static_cast<std::size_t>(n));
    CHECK(order.blocks.front().cols[0] == n - 1);
  }
  SECTION("a large ring is one block (iterative Tarjan)") {
    const int n = 3000;
    std::vector<int> rows, cols;
    for (int r = 0; r < n; ++r) {
      rows.insert(rows.end(), {r, r});
      cols.insert(cols.end(), {r, (r + 1) % n});
    }
    const auto order = cg::blt_order(n, n, rows, cols);
    check_blt(order, n, rows, cols);
    CHECK(order.blocks.size() == 1);
  }
  SECTION("augmenting paths are needed") {
    // Greedy takes r0 -> c0; r1 only has c0, so r0 must move to c1.
    const std::vector<int> rows = {0, 0, 1}, cols = {0, 1, 0};
    const auto order = cg::blt_order(2, 2, rows, cols);
    check_blt(order, 2, rows, cols);
    CHECK(order.blocks.size() == 2);
  }
  SECTION("structurally singular and non-square have no order") {
    CHECK_FALSE(cg::blt_order(2, 2, {0, 1}, {0, 0}).perfect);
    CHECK_FALSE(cg::blt_order(2, 3, {0, 1}, {0, 1}).perfect);
  }
}

TEST_CASE("tearing: a closed chain's block is solved on two tear variables",
          "[structure][tearing]") {
  for (const char* file : {"closed_chain_4", "scissor_lift_3"}) {
    INFO(file);
    const auto model = cg::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                    "/tests/mechanisms/" + file + ".yaml");
    const cg::Structure st = cg::analyze_structure(model->symbolic(), model->symbols());
    std::map<std::pair<int, int>, GiNaC::ex> jac;
    for (const auto& e : model->symbolic().phi_q) jac[{e.row, e.col}] = e.value;
    int torn = 0;
    for (const auto& plan : st.plans) {
      if (!plan.torn()) continue;
      ++torn;
      const auto& b = plan.block;
      // Tears and assigned coordinates partition the block; residual and assigned rows too.
      CHECK(plan.tears.size() == plan.residuals.size());
      CHECK(plan.tears.size() + plan.assigned.size() == b.cols.size());
      CHECK(plan.tears.size() < b.cols.size());
      std::set<int> known(plan.tears.begin(), plan.tears.end());
      std::set<int> rows(plan.residuals.begin(), plan.residuals.end());
      for (std::size_t a = 0; a < plan.assigned.size(); ++a) {
        const auto [r, c] = plan.assigned[a];
        CHECK(rows.insert(r).second);
        CHECK(!known.count(c));
        // The row reads only known coordinates of the block besides c, and is linear in c
        // with a non-zero constant coefficient: the assignment is exact, no iteration.
        for (int other : b.cols)
          if (other != c && jac.count({r, other})) CHECK(known.count(other));
        REQUIRE(jac.count({r, c}));
        CHECK(GiNaC::is_a<GiNaC::numeric>(jac.at({r, c})));
        CHECK(!jac.at({r, c}).is_zero());
        // q[c] = value solves the row whatever the other coordinates are.
        const GiNaC::ex& x = model->symbols().q(c);
        CHECK(model->symbolic().phi[r].subs(x == plan.assigned_value[a]).expand().is_zero());
        known.insert(c);
      }
      CHECK(rows.size() == b.rows.size());
    }
    CHECK(torn > 0);
  }
  // The closed chain's loop block (5 coordinates) needs Newton on 2 of them only: the first
  // coupler's angle and the rocker's; the rest follow from them.
  CHECK(kinegen::models::closed_chain_4::max_block_size == 5);
  CHECK(kinegen::models::closed_chain_4::max_newton_size == 2);
  CHECK(kinegen::models::scissor_lift_3::max_newton_size <
        kinegen::models::scissor_lift_3::max_block_size);
  // A block that cannot be torn keeps Newton on the whole block.
  CHECK(kinegen::models::four_bar::max_newton_size == 2);
}

namespace {

// Block solver (Solver) against the dense solver (DenseSolver) from random starts near the
// solution at random times: the same q, qd and qdd.
template <class Model>
void compare_with_dense(unsigned seed) {
  kinegen::SolverOptions tight;
  tight.tolerance = 1e-14;
  kinegen::Solver<Model> block({}, tight);
  kinegen::DenseSolver<Model> dense({}, tight);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> time(0, 2 * M_PI), nudge(-0.02, 0.02);
  auto q = block.initial_estimate();
  REQUIRE(dense.position(q, 0.0));  // a solved start
  for (int trial = 0; trial < 50; ++trial) {
    // Marching over a turn at random offsets, so each dense solve starts near its solution.
    const double t = 2 * M_PI * trial / 50 + 0.05 * time(rng) / (2 * M_PI);
    REQUIRE(dense.position(q, t));
    const auto qs = q;
    auto qb = qs, qdense = qs;
    for (int k = 0; k < Model::nq; ++k) qb[k] += nudge(rng);
    INFO("t = " << t);
    const kinegen::Result r = block.position(qb, t);
    REQUIRE(r);
    decltype(q) qd_b, qdd_b, qd_d, qdd_d;
    REQUIRE(block.velocity(qb, t, qd_b));
    REQUIRE(block.acceleration(qb, qd_b, t, qdd_b));
    REQUIRE(dense.velocity(qdense, t, qd_d));
    REQUIRE(dense.acceleration(qdense, qd_d, t, qdd_d));
    const double scale = 1 + qdd_d.cwiseAbs().maxCoeff();
    CHECK((qb - qdense).cwiseAbs().maxCoeff() < 1e-13 * Model::length_scale);
    CHECK((qd_b - qd_d).cwiseAbs().maxCoeff() < 1e-13 * (1 + qd_d.cwiseAbs().maxCoeff()));
    CHECK((qdd_b - qdd_d).cwiseAbs().maxCoeff() < 1e-13 * scale);
    // The combined functions give the same numbers as the separate ones.
    decltype(q) qd_c, qdd_c, q_step = qb;
    const auto o = typename Model::BlockOptions{};
    REQUIRE(Model::solve_velocity_acceleration(qb.data(), t, typename Model::Params{}, qd_c.data(),
                                               qdd_c.data(), o)
                .status == 0);
    CHECK((qd_c - qd_b).cwiseAbs().maxCoeff() == 0);
    CHECK((qdd_c - qdd_b).cwiseAbs().maxCoeff() == 0);
    REQUIRE(
        Model::solve_step(q_step.data(), t, typename Model::Params{}, qd_c.data(), qdd_c.data(), o)
            .status == 0);
    CHECK((q_step - qdense).cwiseAbs().maxCoeff() < 1e-13 * Model::length_scale);
    CHECK((qdd_c - qdd_d).cwiseAbs().maxCoeff() < 1e-13 * scale);
  }
}

// step() with the predictor, default and with one fixed iteration, against the dense solver.
template <class Model>
void compare_steps(int fixed_iterations) {
  kinegen::SolverOptions options, tight;
  options.fixed_iterations = fixed_iterations;
  tight.tolerance = 1e-14;
  kinegen::Solver<Model> block({}, options);
  kinegen::DenseSolver<Model> dense({}, tight);
  auto q = block.initial_estimate(), qd = q, qdd = q, qdense = q, qd_d = q, qdd_d = q;
  const double dt = 2 * M_PI / 3600;
  double worst = 0;
  int max_iterations = 0;
  for (int k = 0; k < 3600; ++k) {
    const double t = k * dt;
    const kinegen::Result r = block.step(t, q, qd, qdd);
    REQUIRE(r);
    if (k > 0) max_iterations = std::max(max_iterations, r.iterations);
    qdense = q;
    REQUIRE(dense.position(qdense, t));
    REQUIRE(dense.velocity(qdense, t, qd_d));
    REQUIRE(dense.acceleration(qdense, qd_d, t, qdd_d));
    worst = std::max({worst, (q - qdense).cwiseAbs().maxCoeff() / Model::length_scale,
                      (qd - qd_d).cwiseAbs().maxCoeff() / (1 + qd_d.cwiseAbs().maxCoeff()),
                      (qdd - qdd_d).cwiseAbs().maxCoeff() / (1 + qdd_d.cwiseAbs().maxCoeff())});
  }
  INFO("fixed_iterations " << fixed_iterations << ", worst " << worst);
  CHECK(worst < 1e-12);
  // The predictor leaves at most two iterations per block at 0.1 degree per step.
  CHECK(max_iterations <= (fixed_iterations > 0 ? fixed_iterations : 2));
}

}  // namespace

TEMPLATE_TEST_CASE("block solver matches the dense solver", "[structure][solver]",
                   kinegen::models::slider_crank, kinegen::models::offset_slider_crank,
                   kinegen::models::four_bar, kinegen::models::quick_return,
                   kinegen::models::slider_crank_lecture,
                   // Blocks of 3 to 6 coordinates, where the block LU pivots.
                   kinegen::models::fourbar_chain_3, kinegen::models::scissor_lift_3,
                   kinegen::models::closed_chain_4) {
  STATIC_REQUIRE(kinegen::Solver<TestType>::kBlockSolver);
  compare_with_dense<TestType>(12345);
  compare_steps<TestType>(0);
  compare_steps<TestType>(1);
}

TEMPLATE_TEST_CASE("the block solver reads only newton_coordinates from its start",
                   "[structure][solver]", kinegen::models::slider_crank,
                   kinegen::models::four_bar, kinegen::models::quick_return,
                   kinegen::models::fourbar_chain_3, kinegen::models::scissor_lift_3,
                   kinegen::models::closed_chain_4) {
  // Solver::step predicts only these coordinates; every other one must be computed from them
  // (and from t), whatever q held.
  using M = TestType;
  const typename M::Params p{};
  typename M::BlockOptions o{};
  o.tolerance = 1e-14;
  const double t = 0.3;
  std::array<double, M::nq> solved{};
  for (int k = 0; k < M::nq; ++k) solved[k] = M::q0[k];
  REQUIRE(M::solve_position(solved.data(), t, p, o).status == 0);
  std::set<int> iterated(M::newton_coordinates.begin(), M::newton_coordinates.end());
  CHECK(static_cast<int>(iterated.size()) == M::num_newton_coordinates);
  CHECK(M::num_newton_coordinates <= M::nq);
  std::array<double, M::nq> q = solved;
  for (int k = 0; k < M::nq; ++k)
    if (!iterated.count(k)) q[k] = 1e3 * (k + 1);  // garbage
  const auto r = M::solve_position(q.data(), t, p, o);
  REQUIRE(r.status == 0);
  for (int k = 0; k < M::nq; ++k) {
    INFO("q[" << k << "]");
    CHECK(std::abs(q[k] - solved[k]) <= 1e-12 * (1 + std::abs(solved[k])));
  }
  // And the iterated ones do matter: a wrong start for them costs iterations.
  if (M::num_newton_coordinates > 0) {
    q = solved;
    q[M::newton_coordinates[0]] += 0.01;
    const auto moved = M::solve_position(q.data(), t, p, o);
    REQUIRE(moved.status == 0);
    CHECK(moved.total_iterations > r.total_iterations);
  }
}

TEMPLATE_TEST_CASE("block solver works in float", "[structure][float]",
                   kinegen::models::slider_crank, kinegen::models::four_bar,
                   kinegen::models::quick_return, kinegen::models::closed_chain_4) {
  kinegen::SolverOptions options;
  options.tolerance = 1e-5;
  kinegen::Solver<TestType, float> fsolver({}, options);
  kinegen::Solver<TestType> dsolver;
  auto qf = fsolver.initial_estimate();
  auto qdouble = dsolver.initial_estimate();
  decltype(qf) qdf = qf, qddf = qf;
  decltype(qdouble) qdd_ = qdouble, qddd = qdouble;
  for (int k = 0; k <= 36; ++k) {
    const double t = 2 * M_PI * k / 36;
    REQUIRE(fsolver.position(qf, static_cast<float>(t)));
    REQUIRE(fsolver.velocity(qf, static_cast<float>(t), qdf));
    REQUIRE(fsolver.acceleration(qf, qdf, static_cast<float>(t), qddf));
    REQUIRE(dsolver.position(qdouble, t));
    REQUIRE(dsolver.velocity(qdouble, t, qdd_));
    REQUIRE(dsolver.acceleration(qdouble, qdd_, t, qddd));
    CHECK((qf.template cast<double>() - qdouble).cwiseAbs().maxCoeff() < 1e-4);
    CHECK((qddf.template cast<double>() - qddd).cwiseAbs().maxCoeff() < 1e-3);
  }
}

TEST_CASE("guarded explicit rows: correct, and singular when the coefficient vanishes",
          "[structure]") {
  using M = kinegen::models::guarded_slider;
  STATIC_REQUIRE(M::num_blocks == 6);
  STATIC_REQUIRE(M::num_explicit_blocks == 6);
  M::Params p;
  p.k = 2.5;
  p.omega = 1.3;
  kinegen::Solver<M> solver(p);
  auto q = solver.initial_estimate();
  decltype(q) qd, qdd;
  for (int i = 0; i <= 20; ++i) {
    const double t = 0.37 * i, w = p.omega, s = std::sin(w * t), c = std::cos(w * t);
    REQUIRE(solver.position(q, t));
    REQUIRE(solver.velocity(q, t, qd));
    REQUIRE(solver.acceleration(q, qd, t, qdd));
    // x = cos(wt)/k, y = 1/(2 + sin(wt)): closed forms and their derivatives.
    CHECK(q[3] == Approx(c / p.k).epsilon(1e-14));
    CHECK(qd[3] == Approx(-w * s / p.k).margin(1e-14));
    CHECK(qdd[3] == Approx(-w * w * c / p.k).margin(1e-14));
    CHECK(q[4] == Approx(1 / (2 + s)).epsilon(1e-14));
    CHECK(qd[4] == Approx(-w * c / ((2 + s) * (2 + s))).margin(1e-14));
    CHECK(qdd[4] == Approx(2 * w * w * c * c / std::pow(2 + s, 3) + w * w * s / ((2 + s) * (2 + s)))
                        .margin(1e-13));
  }
  p.k = 0;
  kinegen::Solver<M> singular(p);
  auto q0 = singular.initial_estimate();
  const kinegen::Result r = singular.position(q0, 0.5);
  CHECK(r.status == kinegen::Status::kSingular);
  const auto report = M::solve_position(q0.data(), 0.5, p, M::BlockOptions{});
  CHECK(report.status == 2);
  CHECK(report.block == 3);  // rows 2 -> x_slider
  decltype(q0) qd0;
  CHECK(singular.velocity(q0, 0.5, qd0).status == kinegen::Status::kSingular);
}

TEST_CASE("a singular Newton block is reported", "[structure]") {
  using M = kinegen::models::slider_crank;
  // The rod's block has derivative l*sin(phi_rod): zero at phi_rod = 0.
  double q[M::nq] = {0, 0, 0, 3, 0, 0};
  const auto report = M::solve_position(q, 0.0, M::Params{}, M::BlockOptions{});
  CHECK(report.status == 2);
  CHECK(report.block == 4);
  // The four-bar's 2 x 2 block at a toggle: coupler and rocker collinear makes it singular.
  using F = kinegen::models::four_bar;
  double qf[F::nq] = {0, 0, 0, 1, 0, 0, 3, 0, 0};
  const auto rf = F::solve_position(qf, 0.0, F::Params{}, F::BlockOptions{});
  CHECK(rf.status == 2);
  CHECK(rf.block == 7);
  // Non-finite input is reported as such.
  double qn[M::nq] = {0, 0, 0, 3, 0, NAN};
  CHECK(M::solve_position(qn, 0.0, M::Params{}, M::BlockOptions{}).status == 3);
  // Newton that cannot converge in the budget.
  M::BlockOptions one;
  one.max_iterations = 1;
  double qm[M::nq] = {0, 0, 0, 3, 0, 1.0};
  CHECK(M::solve_position(qm, 0.0, M::Params{}, one).status == 1);
}

TEST_CASE("generate --outputs selects the analyses in the header", "[structure][emit]") {
  const auto model = load("four_bar");
  const auto text = [&](cg::Outputs outputs) {
    cg::EmitOptions options;
    options.outputs = outputs;
    return cg::emit_header(*model, options);
  };
  const auto has = [](const std::string& s, const char* what) {
    return s.find(what) != std::string::npos;
  };
  const std::string all = text(cg::Outputs::kAll), pos = text(cg::Outputs::kPosition),
                    vel = text(cg::Outputs::kVelocity);
  // The default is everything, and the header the CLI writes by default.
  CHECK(all == cg::emit_header(*model));
  for (const char* f : {"static void phi(", "static void phi_q(", "solve_position("}) {
    CHECK(has(all, f));
    CHECK(has(pos, f));
    CHECK(has(vel, f));
  }
  CHECK(has(all, "static void gamma("));
  CHECK(has(all, "solve_step("));
  CHECK(has(all, "has_acceleration = true"));
  CHECK_FALSE(has(pos, "static void nu("));
  CHECK_FALSE(has(pos, "solve_velocity("));
  CHECK_FALSE(has(pos, "static void gamma("));
  CHECK(has(pos, "has_velocity = false"));
  CHECK(has(vel, "static void nu("));
  CHECK(has(vel, "solve_velocity("));
  CHECK_FALSE(has(vel, "static void gamma("));
  CHECK_FALSE(has(vel, "solve_acceleration("));
  CHECK(has(vel, "has_acceleration = false"));
}

// The sin/cos cache of solve_step: anchors keep their exact sin and cos (nothing accumulates
// over many steps), and the solution matches the one without a cache, over a long run with
// small steps (rotations) and jumps (new anchors).
template <class Model>
void check_trig_cache() {
  STATIC_REQUIRE(Model::trig_cache_size > 0);
  std::array<double, Model::trig_cache_size> cache;
  cache.fill(NAN);
  std::array<double, Model::nq> q = Model::q0, qd{}, qdd{}, q2 = Model::q0, qd2{}, qdd2{};
  const typename Model::Params p{};
  const typename Model::BlockOptions o{};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jump(0.05, 1.0);
  double t = 0, worst = 0;
  int steps = 0;
  for (int k = 0; k < 20000; ++k) {
    // Mostly 0.1 degree of crank (rotations from the anchors), every 500th step a jump.
    t += k % 500 == 499 ? jump(rng) : 2 * M_PI / 3600;
    REQUIRE(Model::solve_step(q.data(), t, p, qd.data(), qdd.data(), o, cache.data()).status ==
            0);
    REQUIRE(Model::solve_step(q2.data(), t, p, qd2.data(), qdd2.data(), o).status == 0);
    for (int i = 0; i < Model::nq; ++i) {
      worst = std::max(worst, std::abs(q[i] - q2[i]) / Model::length_scale);
      worst = std::max(worst, std::abs(qd[i] - qd2[i]) / (1 + std::abs(qd2[i])));
      worst = std::max(worst, std::abs(qdd[i] - qdd2[i]) / (1 + std::abs(qdd2[i])));
    }
    ++steps;
  }
  INFO(steps << " steps, worst relative difference " << worst);
  CHECK(worst < 1e-13);
  for (int s = 0; s < Model::trig_cache_size; s += 3) {
    REQUIRE(std::isfinite(cache[s]));
    CHECK(cache[s + 1] == std::sin(cache[s]));
    CHECK(cache[s + 2] == std::cos(cache[s]));
  }
}

TEST_CASE("the sin/cos cache gives the uncached solution and keeps exact anchors",
          "[structure][trig]") {
  check_trig_cache<kinegen::models::four_bar>();
  check_trig_cache<kinegen::models::quick_return>();
  check_trig_cache<kinegen::models::closed_chain_4>();
}
