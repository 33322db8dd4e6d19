// Peer for the dynamics benchmark: Simbody (libsimbody-dev), forward dynamics of the same
// mechanisms built the way a Simbody user builds a planar linkage: Pin mobilizers (rotation
// about z) and a Slider (translation along x) form a tree, PointInPlane constraints close its
// loops (two per revolute that closes one), Force::Gravity and a Force::Custom give the loads
// (the press's motor characteristic and forming force, the same expressions as the file's).
// Integration: RungeKuttaMersonIntegrator at the accuracy given (its default constraint
// tolerance, the same), driven by a TimeStepper to t1. Compiled as C++17 on its own, like the
// kinematic peers (Simbody 3.7's headers do not compile as C++20).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>

#include "dynamics_peers.hpp"

#if KINEGEN_HAVE_SIMBODY
#include <Simbody.h>
#endif

namespace kinegen::bench::dynamics {

#if !KINEGEN_HAVE_SIMBODY
std::vector<Run> run_simbody(const Problem&, const std::vector<double>&, int,
                             std::string& skipped) {
  skipped =
      "simbody: skipped: Simbody not found when the benchmark was configured "
      "(scripts/bench_setup.sh installs libsimbody-dev)";
  return {};
}
#else
namespace {

using namespace SimTK;

// A planar body: mass m, inertia j about its centre of mass at `com` (body frame).
Body::Rigid planar_body(double m, double j, Vec3 com) {
  const Inertia about_com(Vec3(j, j, j));
  return Body::Rigid(MassProperties(m, com, about_com.shiftFromMassCenter(com, m)));
}

// The press's loads, from the file's parameters: the motor's torque T0 (1 - omega/omega0) on
// the crank, and the forming force -F poly345(depth/ramp) poly345(v/vs) on the ram along x.
class PressLoads : public Force::Custom::Implementation {
 public:
  PressLoads(const Problem& p, MobilizedBody crank, MobilizedBody ram)
      : p_(p), crank_(crank), ram_(ram) {}
  void calcForce(const State& s, Vector_<SpatialVec>&, Vector_<Vec3>&,
                 Vector& mobility) const override {
    const double w = crank_.getOneU(s, 0);
    crank_.applyOneMobilityForce(s, 0, p_.param("T0") * (1 - w / p_.param("omega0")), mobility);
    const double x = ram_.getOneQ(s, 0), v = ram_.getOneU(s, 0);
    const double depth = x - (p_.param("r") + p_.param("l") - p_.param("contact"));
    const double f = -p_.param("F") * poly345(depth / p_.param("ramp")) * poly345(v / p_.param("vs"));
    ram_.applyOneMobilityForce(s, 0, f, mobility);
  }
  Real calcPotentialEnergy(const State&) const override { return 0; }

 private:
  static double poly345(double x) {
    if (x <= 0) return 0;
    if (x >= 1) return 1;
    return x * x * x * (10 - 15 * x + 6 * x * x);
  }
  const Problem& p_;
  MobilizedBody crank_, ram_;
};

// One model: the system, the mobilized body whose pin angle is z, and its initial state.
struct Model {
  MultibodySystem system;
  SimbodyMatterSubsystem matter{system};
  GeneralForceSubsystem forces{system};
  MobilizedBody z_body;
  std::vector<std::pair<MobilizedBody, std::pair<double, double>>> initial;  // q, u per body
};

// A revolute that closes a loop: a's point on_a at b's point on_b, two planar equations (the
// point's x and y in b's frame).
void closing_pin(MobilizedBody a, Vec3 on_a, MobilizedBody b, Vec3 on_b) {
  Constraint::PointInPlane(b, UnitVec3(XAxis), on_b[0], a, on_a);
  Constraint::PointInPlane(b, UnitVec3(YAxis), on_b[1], a, on_a);
}

void build(const Problem& p, Model& md) {
  if (p.name == "pendulum") {
    const double m = p.param("m"), a = p.param("a");
    Force::Gravity(md.forces, md.matter, -YAxis, p.param("g"));
    MobilizedBody::Pin rod(md.matter.Ground(), Transform(),
                           planar_body(m, m * 4 * a * a / 12, Vec3(a, 0, 0)), Transform());
    md.z_body = rod;
    md.initial = {{rod, {p.z0, p.zd0}}};
  } else if (p.name == "press_flywheel") {
    const double r = p.param("r"), l = p.param("l");
    Force::Gravity(md.forces, md.matter, -YAxis, 9.81);
    // The file's crank is massless with the flywheel's inertia J; Simbody refuses inertia
    // without mass, so it gets 1 kg on its axis, which changes nothing: the pin holds that
    // point still, and gravity's moment about it is 0.
    const double j = p.param("J");
    MobilizedBody::Pin crank(md.matter.Ground(), Transform(),
                             Body::Rigid(MassProperties(1, Vec3(0), Inertia(Vec3(j, j, j)))),
                             Transform());
    MobilizedBody::Pin rod(crank, Transform(Vec3(r, 0, 0)),
                           planar_body(1.2, 0.004, Vec3(0.1, 0, 0)), Transform());
    MobilizedBody::Slider ram(md.matter.Ground(), Transform(),
                              Body::Rigid(MassProperties(6, Vec3(0), Inertia(0))), Transform());
    closing_pin(rod, Vec3(l, 0, 0), ram, Vec3(0));
    Force::Custom(md.forces, new PressLoads(p, crank, ram));
    md.z_body = crank;
    // At the back dead centre: the rod along +x from the crank pin at (-r, 0).
    md.initial = {{crank, {p.z0, p.zd0}}, {rod, {-p.z0, -p.zd0}}, {ram, {l - r, 0}}};
  } else {  // n_four_bar: N + 1 unit cranks on ground pins at x = 0..N, N unit couplers
    const double m = p.param("m"), l = p.param("l");
    Force::Gravity(md.forces, md.matter, -YAxis, p.param("g"));
    const Body::Rigid rod = planar_body(m, m * l * l / 12, Vec3(l / 2, 0, 0));
    std::vector<MobilizedBody> cranks;
    for (int k = 0; k <= p.n; ++k) {
      MobilizedBody::Pin c(md.matter.Ground(), Transform(Vec3(k * l, 0, 0)), rod, Transform());
      cranks.push_back(c);
      md.initial.push_back({c, {p.z0, p.zd0}});
    }
    for (int k = 0; k < p.n; ++k) {
      // The coupler on crank k's tip, horizontal on the parallelogram branch; its end on
      // crank k + 1's tip.
      MobilizedBody::Pin c(cranks[k], Transform(Vec3(l, 0, 0)), rod, Transform());
      closing_pin(c, Vec3(l, 0, 0), cranks[k + 1], Vec3(l, 0, 0));
      md.initial.push_back({c, {-p.z0, -p.zd0}});
    }
    md.z_body = cranks[0];
  }
}

}  // namespace

std::vector<Run> run_simbody(const Problem& p, const std::vector<double>& tolerances,
                             int repetitions, std::string& skipped) {
  (void)skipped;
  std::vector<Run> out;
  for (double accuracy : tolerances) {
    Run run;
    run.method = "simbody";
    char label[32];
    std::snprintf(label, sizeof label, "acc=%.0e", accuracy);
    run.setting = label;
    Model md;
    build(p, md);
    md.system.realizeTopology();
    double best = INFINITY;
    for (int rep = 0; rep < repetitions; ++rep) {
      State state = md.system.getDefaultState();
      for (auto& [body, qu] : md.initial) {
        body.setOneQ(state, 0, qu.first);
        body.setOneU(state, 0, qu.second);
      }
      try {
        const auto start = std::chrono::steady_clock::now();
        md.system.project(state, 1e-14);
        RungeKuttaMersonIntegrator integ(md.system);
        integ.setAccuracy(accuracy);
        TimeStepper ts(md.system, integ);
        ts.initialize(state);
        ts.stepTo(p.t1);
        const auto stop = std::chrono::steady_clock::now();
        best = std::min(best, std::chrono::duration<double>(stop - start).count());
        const State& end = integ.getState();
        run.z = md.z_body.getOneQ(end, 0);
        run.zd = md.z_body.getOneU(end, 0);
        run.steps = integ.getNumStepsTaken();
        if (std::abs(end.getTime() - p.t1) > 1e-9 * std::max(1.0, p.t1)) {
          run.ok = false;
          run.note = "stopped at t = " + std::to_string(end.getTime());
          break;
        }
      } catch (const std::exception& e) {
        run.ok = false;
        const std::string what = e.what();
        run.note = what.substr(0, what.find('\n'));
        break;
      }
    }
    run.seconds = best;
    out.push_back(std::move(run));
  }
  return out;
}
#endif

}  // namespace kinegen::bench::dynamics
