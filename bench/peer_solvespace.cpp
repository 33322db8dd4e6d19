// Peer: SolveSpace's constraint solver library (libslvs, C API Slvs_Solve); position only.
//
// The linkage is sketched in a 2D workplane the way a SolveSpace user would: ground points
// and a ground "crank direction" line (group 1, constants), and the moving joint points as
// unknowns (group 2). The crank is driven by keeping its tip on the direction line at angle
// omega t at distance a from the pivot; the tip and the other joint points are solved by
// Slvs_Solve, warm-started from the previous step (parameters stay in place). The kinegen
// coordinates q are then read off the points (angles by atan2, made continuous).
#include <cmath>
#include <cstring>

#include "four_bar.hpp"
#include "slider_crank.hpp"
#include "work_precision.hpp"

#if KINEGEN_HAVE_SLVS
#include <slvs.h>
#endif

namespace kinegen::bench {

#if !KINEGEN_HAVE_SLVS
std::vector<RunResult> run_solvespace(const std::string&, const BenchGrid&, std::string& skipped) {
  skipped =
      "solvespace: skipped: libslvs not found when the benchmark was configured "
      "(scripts/bench_setup.sh installs libslvs1-dev)";
  return {};
}
#else
namespace {

// The angle nearest `previous` that equals `a` modulo 2 pi.
double continuous(double a, double previous) {
  return previous + std::remainder(a - previous, 2 * M_PI);
}

class SlvsSketch {
 public:
  SlvsSketch() {
    // Workplane: origin (0,0,0), normal = identity quaternion (the xy plane).
    param(1, 0);
    param(1, 0);
    param(1, 0);
    const Slvs_hEntity origin = entity(Slvs_MakePoint3d(next_e_, 1, 1, 2, 3));
    param(1, 1);
    param(1, 0);
    param(1, 0);
    param(1, 0);
    const Slvs_hEntity normal = entity(Slvs_MakeNormal3d(next_e_, 1, 4, 5, 6, 7));
    wp_ = entity(Slvs_MakeWorkplane(next_e_, 1, origin, normal));
  }
  // A point in the workplane; group 1 = fixed, group 2 = unknown. Returns the entity.
  Slvs_hEntity point(int group, double u, double v, Slvs_hParam& pu) {
    pu = param(group, u);
    param(group, v);
    return entity(Slvs_MakePoint2d(next_e_, group, wp_, pu, pu + 1));
  }
  Slvs_hEntity line(Slvs_hEntity a, Slvs_hEntity b) {
    return entity(Slvs_MakeLineSegment(next_e_, 1, wp_, a, b));
  }
  void distance(Slvs_hEntity a, Slvs_hEntity b, double value) {
    constraints_.push_back(
        Slvs_MakeConstraint(static_cast<Slvs_hConstraint>(constraints_.size() + 1), 2,
                            SLVS_C_PT_PT_DISTANCE, wp_, value, a, b, 0, 0));
  }
  void on_line(Slvs_hEntity p, Slvs_hEntity l) {
    constraints_.push_back(
        Slvs_MakeConstraint(static_cast<Slvs_hConstraint>(constraints_.size() + 1), 2,
                            SLVS_C_PT_ON_LINE, wp_, 0, p, 0, l, 0));
  }
  double& value(Slvs_hParam h) { return params_[h - 1].val; }
  bool solve() {
    Slvs_System sys;
    std::memset(&sys, 0, sizeof sys);
    sys.param = params_.data();
    sys.params = static_cast<int>(params_.size());
    sys.entity = entities_.data();
    sys.entities = static_cast<int>(entities_.size());
    sys.constraint = constraints_.data();
    sys.constraints = static_cast<int>(constraints_.size());
    failed_.resize(constraints_.size());
    sys.failed = failed_.data();
    sys.faileds = static_cast<int>(failed_.size());
    sys.calculateFaileds = 0;
    Slvs_Solve(&sys, 2);
    return sys.result == SLVS_RESULT_OKAY;
  }

 private:
  Slvs_hParam param(int group, double v) {
    params_.push_back(Slvs_MakeParam(static_cast<Slvs_hParam>(params_.size() + 1), group, v));
    return params_.back().h;
  }
  Slvs_hEntity entity(Slvs_Entity e) {
    entities_.push_back(e);
    return next_e_++;
  }
  std::vector<Slvs_Param> params_;
  std::vector<Slvs_Entity> entities_;
  std::vector<Slvs_Constraint> constraints_;
  std::vector<Slvs_hConstraint> failed_;
  Slvs_hEntity next_e_ = 1;
  Slvs_hEntity wp_ = 0;
};

}  // namespace

std::vector<RunResult> run_solvespace(const std::string& example, const BenchGrid& g,
                                      std::string& skipped) {
  RunResult result;
  result.method = "solvespace";
  result.setting = "default";
  result.position_only = true;
  result.note = "position only";
  const bool four_bar = example == "four_bar";
  if (!four_bar && example != "slider_crank") {
    skipped = "solvespace: not modelled for " + example;
    return {};
  }
  const models::four_bar::Params fb{};
  const models::slider_crank::Params sc{};
  const double a = four_bar ? fb.a : 1.0, omega = four_bar ? fb.omega : sc.omega;

  SlvsSketch sk;
  Slvs_hParam p_o, p_dir, p_a, p_b, p_o4 = 0, p_x1 = 0;
  const Slvs_hEntity o = sk.point(1, 0, 0, p_o);
  const Slvs_hEntity dir = sk.point(1, a, 0, p_dir);  // crank direction, moved each step
  const Slvs_hEntity crank_line = sk.line(o, dir);
  const Slvs_hEntity tip = sk.point(2, a, 0, p_a);
  sk.distance(o, tip, a);
  sk.on_line(tip, crank_line);
  Slvs_hEntity b;
  if (four_bar) {
    const Slvs_hEntity o4 = sk.point(1, fb.d, 0, p_o4);
    const double phi_r = models::four_bar::q0[8];
    b = sk.point(2, fb.d + fb.c * std::cos(phi_r), fb.c * std::sin(phi_r), p_b);
    sk.distance(tip, b, fb.b);
    sk.distance(o4, b, fb.c);
  } else {
    const Slvs_hEntity x1 = sk.point(1, 1, 0, p_x1);  // the slider's line: the x axis
    const Slvs_hEntity axis = sk.line(o, x1);
    b = sk.point(2, 1 + sc.l, 0, p_b);  // the slider
    sk.distance(tip, b, sc.l);
    sk.on_line(b, axis);
  }
  (void)b;

  const double A0x = sk.value(p_a), A0y = sk.value(p_a + 1);
  const double B0x = sk.value(p_b), B0y = sk.value(p_b + 1);
  std::vector<Sample> samples;
  double fail_t = NAN;
  double phi1 = 0, phi2 = 0;
  auto reset = [&] {
    sk.value(p_a) = A0x;
    sk.value(p_a + 1) = A0y;
    sk.value(p_b) = B0x;
    sk.value(p_b + 1) = B0y;
    phi1 = four_bar ? models::four_bar::q0[5] : models::slider_crank::q0[5];
    phi2 = four_bar ? models::four_bar::q0[8] : 0;
    samples.clear();
  };
  auto step = [&](int k, bool record) {
    const double t = g.grid.at(k);
    sk.value(p_dir) = 2 * a * std::cos(omega * t);
    sk.value(p_dir + 1) = 2 * a * std::sin(omega * t);
    if (!sk.solve()) {
      fail_t = t;
      return false;
    }
    const double ax = sk.value(p_a), ay = sk.value(p_a + 1);
    const double bx = sk.value(p_b), by = sk.value(p_b + 1);
    const double phi0 = continuous(std::atan2(ay, ax), omega * t);
    Eigen::VectorXd q;
    if (four_bar) {
      phi1 = continuous(std::atan2(by - ay, bx - ax), phi1);
      phi2 = continuous(std::atan2(by, bx - fb.d), phi2);
      q.resize(9);
      q << 0, 0, phi0, ax, ay, phi1, sk.value(p_o4), sk.value(p_o4 + 1), phi2;
    } else {
      // rod origin at the slider B; rod-local [0, l] at the crank tip A
      phi1 = continuous(std::atan2(-(ax - bx), ay - by), phi1);
      q.resize(6);
      q << 0, 0, phi0, bx, by, phi1;
    }
    if (record) samples.push_back(Sample{q, {}, {}});
    return true;
  };
  (void)p_x1;
  result.ns_per_step = time_steps(g, step, reset);
  if (std::isnan(result.ns_per_step)) {
    result.ok = false;
    result.note = "Slvs_Solve failed at t = " + std::to_string(fail_t);
  }
  result.samples = std::move(samples);
  std::vector<RunResult> out;
  out.push_back(std::move(result));
  return out;
}
#endif

}  // namespace kinegen::bench
