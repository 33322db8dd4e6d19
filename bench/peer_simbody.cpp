// Peer: Simbody (libsimbody-dev). The planar linkage is a tree of Pin mobilizers (rotation
// about z) closed by constraints, the crank driven by a prescribed-position Motion q = omega t.
// One step: State::setTime(t), System::project(state, accuracy) (applies the prescribed motion,
// then Newton-type least-squares projection of q onto the position constraints and of u onto
// the velocity constraints, warm-started from the previous step's state), then
// realize(Acceleration), which solves for udot satisfying the acceleration constraints (the
// mechanism has one degree of freedom and it is prescribed, so udot is fully kinematic). The
// kinegen coordinates are read off the bodies (origins) and the pin angles (continuous).
#include <cmath>

#include "four_bar.hpp"
#include "slider_crank.hpp"
#include "work_precision.hpp"

#if KINEGEN_HAVE_SIMBODY
#include <Simbody.h>
#endif

namespace kinegen::bench {

#if !KINEGEN_HAVE_SIMBODY
std::vector<RunResult> run_simbody(const std::string&, const BenchGrid&, std::string& skipped) {
  skipped =
      "simbody: skipped: Simbody not found when the benchmark was configured "
      "(scripts/bench_setup.sh installs libsimbody-dev)";
  return {};
}
#else
namespace {

using namespace SimTK;

// q = omega t on one pin.
class CrankMotion : public Motion::Custom::Implementation {
 public:
  explicit CrankMotion(double omega) : omega_(omega) {}
  Implementation* clone() const override { return new CrankMotion(*this); }
  Motion::Level getLevel(const State&) const override { return Motion::Position; }
  void calcPrescribedPosition(const State& s, int, Real* q) const override {
    q[0] = omega_ * s.getTime();
  }
  void calcPrescribedPositionDot(const State&, int, Real* qdot) const override { qdot[0] = omega_; }
  void calcPrescribedPositionDotDot(const State&, int, Real* qdotdot) const override {
    qdotdot[0] = 0;
  }

 private:
  double omega_;
};

// One linkage: the crank and up to two more pins; `angle_of[b]` lists which pins' angles add
// up to body b's absolute angle.
struct Linkage {
  MultibodySystem system;
  SimbodyMatterSubsystem matter{system};
  GeneralForceSubsystem forces{system};
  std::vector<MobilizedBody> bodies;  // in kinegen's body order
  std::vector<std::vector<int> > angle_of;
  Body::Rigid rigid{MassProperties(1, Vec3(0), UnitInertia(1))};
};

}  // namespace

std::vector<RunResult> run_simbody(const std::string& example, const BenchGrid& g,
                                   std::string& skipped) {
  const bool four_bar = example == "four_bar";
  if (!four_bar && example != "slider_crank") {
    skipped = "simbody: not modelled for " + example;
    return {};
  }
  std::vector<RunResult> out;
  for (double accuracy : {1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14}) {
    RunResult result;
    result.method = "simbody";
    char label[32];
    std::snprintf(label, sizeof label, "acc=%.0e", accuracy);
    result.setting = label;

    Linkage lk;
    std::vector<double> q_init;
    if (four_bar) {
      const models::four_bar::Params p{};
      MobilizedBody::Pin crank(lk.matter.Ground(), Transform(), lk.rigid, Transform());
      MobilizedBody::Pin coupler(crank, Transform(Vec3(p.a, 0, 0)), lk.rigid, Transform());
      MobilizedBody::Pin rocker(lk.matter.Ground(), Transform(Vec3(p.d, 0, 0)), lk.rigid,
                                Transform());
      // Revolute B: coupler point [b, 0] at rocker point [c, 0], two planar equations.
      Constraint::PointInPlane(rocker, UnitVec3(XAxis), p.c, coupler, Vec3(p.b, 0, 0));
      Constraint::PointInPlane(rocker, UnitVec3(YAxis), 0, coupler, Vec3(p.b, 0, 0));
      Motion::Custom(crank, new CrankMotion(p.omega));
      lk.bodies = {crank, coupler, rocker};
      lk.angle_of = {{0}, {0, 1}, {2}};
      const auto& q0 = models::four_bar::q0;
      q_init = {q0[2], q0[5] - q0[2], q0[8]};
    } else {
      const models::slider_crank::Params p{};
      MobilizedBody::Pin crank(lk.matter.Ground(), Transform(), lk.rigid, Transform());
      // rod frame: origin at the slider, rod-local [0, l] pinned to the crank tip [1, 0]
      MobilizedBody::Pin rod(crank, Transform(Vec3(1, 0, 0)), lk.rigid, Transform(Vec3(0, p.l, 0)));
      // slider on the global x axis
      Constraint::PointInPlane(lk.matter.Ground(), UnitVec3(YAxis), 0, rod, Vec3(0));
      Motion::Custom(crank, new CrankMotion(p.omega));
      lk.bodies = {crank, rod};
      lk.angle_of = {{0}, {0, 1}};
      const auto& q0 = models::slider_crank::q0;
      q_init = {q0[2], q0[5] - q0[2]};
    }
    lk.system.realizeTopology();
    State state = lk.system.getDefaultState();
    const int nb = static_cast<int>(lk.bodies.size());

    std::vector<Sample> samples;
    double fail_t = NAN;
    std::string fail_what;
    auto reset = [&] {
      state = lk.system.getDefaultState();
      for (int b = 0; b < nb; ++b) lk.bodies[b].setOneQ(state, 0, q_init[b]);
      samples.clear();
    };
    auto step = [&](int k, bool record) {
      const double t = g.grid.at(k);
      state.setTime(t);
      try {
        lk.system.project(state, accuracy);
      } catch (const std::exception& e) {
        fail_t = t;
        fail_what = e.what();
        return false;
      }
      lk.system.realize(state, Stage::Acceleration);
      if (record) {
        Sample s;
        s.q.resize(3 * nb);
        s.qd.resize(3 * nb);
        s.qdd.resize(3 * nb);
        for (int b = 0; b < nb; ++b) {
          const MobilizedBody& m = lk.bodies[b];
          const Vec3 r = m.getBodyOriginLocation(state), v = m.getBodyOriginVelocity(state),
                     a = m.getBodyOriginAcceleration(state);
          double phi = 0, w = 0, al = 0;
          for (int j : lk.angle_of[b]) {
            phi += lk.bodies[j].getOneQ(state, 0);
            w += lk.bodies[j].getOneU(state, 0);
            al += lk.bodies[j].getOneUDot(state, 0);
          }
          s.q.segment<3>(3 * b) << r[0], r[1], phi;
          s.qd.segment<3>(3 * b) << v[0], v[1], w;
          s.qdd.segment<3>(3 * b) << a[0], a[1], al;
        }
        samples.push_back(std::move(s));
      }
      return true;
    };
    result.ns_per_step = time_steps(g, step, reset);
    if (std::isnan(result.ns_per_step)) {
      result.ok = false;
      result.note = "project failed at t = " + std::to_string(fail_t) + ": " +
                    fail_what.substr(0, fail_what.find('\n'));
    }
    result.samples = std::move(samples);
    out.push_back(std::move(result));
  }
  return out;
}
#endif

}  // namespace kinegen::bench
