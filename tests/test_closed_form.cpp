// Position, velocity and acceleration of every example mechanism over a full crank turn,
// against the hand-derived closed forms of tests/support/closed_form.hpp: (a) through
// kinegen::Solver<Model> on the committed generated headers, (b) through the in-process
// run_analysis on examples/*.yaml, including the named points; with the files' parameters and
// with other lengths and a negative crank speed.
#include <Eigen/Dense>
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <iterator>
#include <kinegen/solver.hpp>
#include <string>
#include <vector>

#include "four_bar.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "offset_slider_crank.hpp"
#include "quick_return.hpp"
#include "slider_crank.hpp"
#include "slider_crank_lecture.hpp"
#include "support/closed_form.hpp"

namespace {

namespace cf = kinegen::closed_form;
namespace cg = kinegen::codegen;

const double kTwoPi = 2 * std::acos(-1.0);

// Newton stops at a scaled step of 1e-10 and converges quadratically, so solved positions sit
// at rounding level; velocities and accelerations come from one linear solve each. The bound
// is on the largest error relative to the largest reference magnitude of the same quantity
// over the run; the errors seen are below 2e-15, so this leaves room for other compilers.
constexpr double kRelTol = 1e-13;

// A named point of a mechanism file: body index (file order) and local offset.
struct PointDef {
  std::string name;
  int body;
  double sx, sy;
};

// Largest absolute error and largest reference magnitude of one quantity over a run.
struct Tracker {
  double err = 0, scale = 0;

  template <class Got, class Want>
  void add(const Got& got, const Want& want) {
    for (std::size_t i = 0; i < std::size(want); ++i) {
      err = std::max(err, std::abs(got[i] - want[i]));
      scale = std::max(scale, std::abs(want[i]));
    }
  }
  double relative() const { return scale > 0 ? err / scale : err; }
};

struct RunErrors {
  Tracker q, qd, qdd;  // coordinates
  Tracker r, v, a;     // named points
  int rows = 0;
};

template <int N, class Vq>
void add_state(RunErrors& e, const Vq& q, const Vq& qd, const Vq& qdd, const cf::State<N>& want) {
  e.q.add(q, want.q);
  e.qd.add(qd, want.qd);
  e.qdd.add(qdd, want.qdd);
}

void check_errors(const RunErrors& e, int steps) {
  INFO("rows " << e.rows << "; max abs (relative) error: q " << e.q.err << " (" << e.q.relative()
               << "), qd " << e.qd.err << " (" << e.qd.relative() << "), qdd " << e.qdd.err << " ("
               << e.qdd.relative() << "); points r " << e.r.err << " (" << e.r.relative() << "), v "
               << e.v.err << " (" << e.v.relative() << "), a " << e.a.err << " (" << e.a.relative()
               << ")");
  CHECK(e.rows == steps + 1);
  CHECK(e.q.relative() < kRelTol);
  CHECK(e.qd.relative() < kRelTol);
  CHECK(e.qdd.relative() < kRelTol);
  CHECK(e.r.relative() < kRelTol);
  CHECK(e.v.relative() < kRelTol);
  CHECK(e.a.relative() < kRelTol);
}

// Mechanism descriptions: the generated model, its closed form and the two ways of setting
// its parameters (generated Params, and overrides for the in-process model).

struct OffsetSliderCrank {
  using Model = kinegen::models::offset_slider_crank;
  using Params = cf::OffsetSliderCrankParams;
  static constexpr int kNq = 9;
  static constexpr const char* kFile = "offset_slider_crank.yaml";
  static cf::State<kNq> state(double t, const Params& p) {
    return cf::offset_slider_crank_state(t, p);
  }
  static Model::Params model_params(const Params& p) {
    Model::Params m;
    m.r = p.r;
    m.l = p.l;
    m.e = p.e;
    m.omega = p.omega;
    return m;
  }
  static std::vector<cg::ParamOverride> overrides(const Params& p) {
    return {{"r", cg::format_number(p.r)},
            {"l", cg::format_number(p.l)},
            {"e", cg::format_number(p.e)},
            {"omega", cg::format_number(p.omega)}};
  }
  static std::vector<PointDef> points(const Params& p) {
    return {{"A", 0, p.r, 0.0}, {"B", 2, 0.0, 0.0}};
  }
  // Still assembles on the same branch: l > r + |e|.
  static Params other() { return {0.75, 3.5, -0.625, -2.5}; }
};

struct FourBar {
  using Model = kinegen::models::four_bar;
  using Params = cf::FourBarParams;
  static constexpr int kNq = 9;
  static constexpr const char* kFile = "four_bar.yaml";
  static cf::State<kNq> state(double t, const Params& p) { return cf::four_bar_state(t, p); }
  static Model::Params model_params(const Params& p) {
    Model::Params m;
    m.a = p.a;
    m.b = p.b;
    m.c = p.c;
    m.d = p.d;
    m.px = p.px;
    m.py = p.py;
    m.omega = p.omega;
    return m;
  }
  static std::vector<cg::ParamOverride> overrides(const Params& p) {
    return {{"a", cg::format_number(p.a)},        {"b", cg::format_number(p.b)},
            {"c", cg::format_number(p.c)},        {"d", cg::format_number(p.d)},
            {"px", cg::format_number(p.px)},      {"py", cg::format_number(p.py)},
            {"omega", cg::format_number(p.omega)}};
  }
  static std::vector<PointDef> points(const Params& p) {
    return {{"A", 0, p.a, 0.0}, {"B", 1, p.b, 0.0}, {"P", 1, p.px, p.py}};
  }
  // Still a Grashof crank-rocker (1.25 + 4 < 3 + 3.5) with |O4 A| in [2.25, 4.75], away from
  // b + c = 7 and |b - c| = 1; the coupler point moves to the other side of the coupler.
  static Params other() { return {1.25, 4.0, 3.0, 3.5, -0.5, 2.0, -2.5}; }
};

struct QuickReturn {
  using Model = kinegen::models::quick_return;
  using Params = cf::QuickReturnParams;
  static constexpr int kNq = 9;
  static constexpr const char* kFile = "quick_return.yaml";
  static cf::State<kNq> state(double t, const Params& p) { return cf::quick_return_state(t, p); }
  static Model::Params model_params(const Params& p) {
    Model::Params m;
    m.r = p.r;
    m.d = p.d;
    m.L = p.L;
    m.omega = p.omega;
    return m;
  }
  static std::vector<cg::ParamOverride> overrides(const Params& p) {
    return {{"r", cg::format_number(p.r)},
            {"d", cg::format_number(p.d)},
            {"L", cg::format_number(p.L)},
            {"omega", cg::format_number(p.omega)}};
  }
  static std::vector<PointDef> points(const Params& p) {
    return {{"A", 2, 0.0, 0.0}, {"tip", 1, p.L, 0.0}};
  }
  static Params other() { return {1.25, 2.5, 3.0, -2.5}; }  // r < d
};

template <class M>
struct SliderCrankBase {
  using Model = M;
  using Params = cf::SliderCrankLectureParams;
  static constexpr int kNq = 6;
  static cf::State<kNq> state(double t, const Params& p) {
    return cf::slider_crank_lecture_state(t, p);
  }
  static typename Model::Params model_params(const Params& p) {
    typename Model::Params m;
    m.l = p.l;
    m.omega = p.omega;
    return m;
  }
  static std::vector<cg::ParamOverride> overrides(const Params& p) {
    return {{"l", cg::format_number(p.l)}, {"omega", cg::format_number(p.omega)}};
  }
  static std::vector<PointDef> points(const Params&) {
    return {{"tip", 0, 1.0, 0.0}, {"slider", 1, 0.0, 0.0}};
  }
  static Params other() { return {2.75, -2.5}; }  // l > 1
};

struct SliderCrank : SliderCrankBase<kinegen::models::slider_crank> {
  static constexpr const char* kFile = "slider_crank.yaml";
};

struct SliderCrankLecture : SliderCrankBase<kinegen::models::slider_crank_lecture> {
  static constexpr const char* kFile = "slider_crank_lecture.yaml";
};

// A full crank turn, whatever the sign of omega, on the CLI's grid t_k = k (t1 - t0) / steps.
double full_turn(double omega) { return kTwoPi / std::abs(omega); }
double grid_time(double t1, int k, int steps) { return 0.0 + k * (t1 - 0.0) / steps; }

// (a) Solver<Model> on the generated header; each position solve starts from the previous
// solution (the first from the file's q0), with no predictor, as a user would drive it.
template <class Case>
RunErrors run_solver(const typename Case::Params& p, int steps) {
  kinegen::Solver<typename Case::Model> solver(Case::model_params(p));
  auto q = solver.initial_estimate();
  decltype(q) qd, qdd;
  const auto points = Case::points(p);
  const double t1 = full_turn(p.omega);
  RunErrors e;
  for (int k = 0; k <= steps; ++k) {
    const double t = grid_time(t1, k, steps);
    if (auto r = solver.position(q, t); !r)
      FAIL("position failed at t = " << t << ": " << r.message());
    if (auto r = solver.velocity(q, t, qd); !r)
      FAIL("velocity failed at t = " << t << ": " << r.message());
    if (auto r = solver.acceleration(q, qd, t, qdd); !r)
      FAIL("acceleration failed at t = " << t << ": " << r.message());
    const cf::State<Case::kNq> want = Case::state(t, p);
    add_state(e, q, qd, qdd, want);
    // Named points from the solved state, against the same points of the closed form.
    cf::State<Case::kNq> got;
    for (int i = 0; i < Case::kNq; ++i) {
      got.q[i] = q[i];
      got.qd[i] = qd[i];
      got.qdd[i] = qdd[i];
    }
    for (const PointDef& d : points) {
      const cf::PointState g = cf::point_state(got, d.body, d.sx, d.sy);
      const cf::PointState w = cf::point_state(want, d.body, d.sx, d.sy);
      e.r.add(g.r, w.r);
      e.v.add(g.v, w.v);
      e.a.add(g.a, w.a);
    }
    ++e.rows;
  }
  return e;
}

// (b) The in-process analysis on the example file, named points as the tool computes them.
template <class Case>
RunErrors run_in_process(const typename Case::Params& p, int steps) {
  const auto model = cg::CompiledModel::from_file(
      std::string(KINEGEN_SOURCE_DIR) + "/examples/" + Case::kFile, Case::overrides(p));
  REQUIRE(model->nq() == Case::kNq);
  const auto points = Case::points(p);
  const auto& declared = model->mechanism().points;
  REQUIRE(declared.size() == points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    REQUIRE(declared[i].name == points[i].name);
    REQUIRE(declared[i].body == points[i].body);
  }
  const double t1 = full_turn(p.omega);
  RunErrors e;
  cg::run_analysis(*model, {0.0, t1, steps}, [&](const cg::StateRow& row) {
    // Rows arrive in grid order; the closed form is evaluated at the row's own time.
    if (row.t != grid_time(t1, e.rows, steps)) FAIL("row " << e.rows << " at t = " << row.t);
    const cf::State<Case::kNq> want = Case::state(row.t, p);
    add_state(e, row.q, row.qd, row.qdd, want);
    if (row.points.size() != points.size()) FAIL("row at t = " << row.t << " lacks points");
    for (std::size_t i = 0; i < points.size(); ++i) {
      const cf::PointState w = cf::point_state(want, points[i].body, points[i].sx, points[i].sy);
      e.r.add(row.points[i].r, w.r);
      e.v.add(row.points[i].v, w.v);
      e.a.add(row.points[i].a, w.a);
    }
    ++e.rows;
  });
  return e;
}

}  // namespace

#define KINEGEN_CLOSED_FORM_CASES \
  OffsetSliderCrank, FourBar, QuickReturn, SliderCrank, SliderCrankLecture

TEMPLATE_TEST_CASE("Solver on the generated header matches the closed form over a crank turn",
                   "[closed-form][solver]", KINEGEN_CLOSED_FORM_CASES) {
  const int steps = GENERATE(720, 36);
  INFO(TestType::kFile << ", " << steps << " steps");
  check_errors(run_solver<TestType>({}, steps), steps);
}

TEMPLATE_TEST_CASE("run_analysis matches the closed form over a crank turn",
                   "[closed-form][analysis]", KINEGEN_CLOSED_FORM_CASES) {
  const int steps = GENERATE(720, 36);
  INFO(TestType::kFile << ", " << steps << " steps");
  check_errors(run_in_process<TestType>({}, steps), steps);
}

TEMPLATE_TEST_CASE("other lengths and omega = -2.5 match the closed form", "[closed-form][params]",
                   KINEGEN_CLOSED_FORM_CASES) {
  const typename TestType::Params p = TestType::other();
  REQUIRE(p.omega == -2.5);
  const int steps = GENERATE(720, 36);
  INFO(TestType::kFile << " with other parameters, " << steps << " steps");
  SECTION("Solver<Model>(params)") { check_errors(run_solver<TestType>(p, steps), steps); }
  SECTION("run_analysis with parameter overrides") {
    check_errors(run_in_process<TestType>(p, steps), steps);
  }
}

// The comparison must be able to fail: the closed form at other parameters is far off.
TEST_CASE("closed-form comparison detects a wrong parameter", "[closed-form]") {
  const RunErrors right = run_solver<FourBar>({}, 36);
  FourBar::Params wrong;
  wrong.c += 1e-9;  // the solver gets the file's rocker length, the reference another one
  RunErrors e;
  kinegen::Solver<FourBar::Model> solver;
  auto q = solver.initial_estimate();
  decltype(q) qd, qdd;
  for (int k = 0; k <= 36; ++k) {
    const double t = grid_time(kTwoPi, k, 36);
    REQUIRE(solver.position(q, t));
    REQUIRE(solver.velocity(q, t, qd));
    REQUIRE(solver.acceleration(q, qd, t, qdd));
    add_state(e, q, qd, qdd, FourBar::state(t, wrong));
  }
  INFO("right " << right.q.relative() << ", wrong " << e.q.relative());
  CHECK(right.q.relative() < kRelTol);
  CHECK(e.q.relative() > kRelTol);
}
