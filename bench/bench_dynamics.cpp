// Work-precision of forward dynamics (issue 24): run time against the error at the end time,
// for the pendulum, the press with its flywheel and the N-four-bar at N = 40, by
//   - kinegen simulate (in-process run_simulation: the minimal coordinates on CVODE, and the
//     augmented method where it is built),
//   - the generated dynamics() of the committed header (peer_generated_dynamics.cpp): its
//     fixed-step step_rk4() at several step sizes, and CVODE on dynamics() as kinegen simulate
//     sets CVODE up,
//   - Simbody (peer_simbody_dynamics.cpp),
//   - the generic Cartesian index-1 DAE with Baumgarte's stabilization on SUNDIALS IDA
//     (generic_dae.hpp).
// Each method integrates from t0 = 0 to t1 once per tolerance; the time is the best of up to
// three runs (a run longer than half a second runs once), the model built beforehand. The
// error is |z(t1) - zref(t1)| of the free coordinate (a crank angle, rad), and of its rate
// relative to the largest |zd| of the reference. References: the closed form of the reduced
// one-degree-of-freedom model theta'' = -w^2 cos(theta) (the pendulum, and the N-four-bar on
// its parallelogram branch) by Jacobi's elliptic functions (Boost.Math, long double); for the
// press, kinegen simulate at rtol 1e-13, checked against the other methods' tightest runs.
//   build/bench/bench_dynamics [OUT.csv] [--quick]       (scripts/bench_dynamics.sh)
#include <boost/math/special_functions/ellint_1.hpp>
#include <boost/math/special_functions/jacobi_elliptic.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "dynamics_peers.hpp"
#include "generic_dae.hpp"
#include "kinegen/codegen/analysis/simulate.hpp"

namespace kd = kinegen::bench::dynamics;
namespace kc = kinegen::codegen;

namespace {

// The N-four-bar after the IFToMM benchmark A02 (as examples/dynamics/n_four_bar.py writes
// it): N + 1 unit cranks on ground pins at x = 0..N, N unit couplers, uniform 1 kg rods,
// gravity, crank 0 at 45 degrees with B0's x-velocity 1 m/s (theta' = -sqrt(2) rad/s).
std::string n_four_bar_yaml(int n) {
  std::string y = "name: n_four_bar_" + std::to_string(n) +
                  "\nparameters:\n  m: 1.0\n  l: 1.0\n  g: 9.81\ngravity: [0, -g]\nbodies:\n";
  const double c = std::cos(M_PI / 4), s = std::sin(M_PI / 4);
  char line[256];
  for (int k = 0; k <= n; ++k) {
    std::snprintf(line, sizeof line,
                  "  - {name: crank_%d, q0: [%d, 0, 0.7853981633974483], mass: m, "
                  "inertia: \"m*l^2/12\", com: [\"l/2\", 0]}\n",
                  k, k);
    y += line;
  }
  for (int k = 0; k < n; ++k) {
    std::snprintf(line, sizeof line,
                  "  - {name: coupler_%d, q0: [%.17g, %.17g, 0], mass: m, inertia: \"m*l^2/12\", "
                  "com: [\"l/2\", 0]}\n",
                  k, k + c, s);
    y += line;
  }
  y += "joints:\n";
  for (int k = 0; k <= n; ++k) {
    std::snprintf(line, sizeof line,
                  "  - {type: revolute, name: O%d, i: ground, j: crank_%d, si: [\"%d*l\", 0]}\n",
                  k, k, k);
    y += line;
  }
  for (int k = 0; k < n; ++k) {
    std::snprintf(line, sizeof line,
                  "  - {type: revolute, name: A%d, i: crank_%d, j: coupler_%d, si: [l, 0]}\n"
                  "  - {type: revolute, name: B%d, i: coupler_%d, j: crank_%d, si: [l, 0], "
                  "sj: [l, 0]}\n",
                  k, k, k, k, k, k + 1);
    y += line;
  }
  y += "free:\n  - {type: absolute_angle, name: theta, body: crank_0, value0: \"pi/4\", "
       "v0: \"-sqrt(2)\"}\n";
  return y;
}

struct Loaded {
  std::unique_ptr<kc::CompiledModel> model;
  kc::ForceModel forces;
  kd::Problem problem;
};

Loaded load(const std::string& path, kd::Problem p) {
  Loaded l;
  kc::BuildOptions build;
  build.free_as_state = true;
  l.model = kc::CompiledModel::from_file(path, {}, build);
  l.forces = kc::derive_forces(*l.model);
  for (const auto& [name, value] : l.model->parameter_table()) p.params[name] = value;
  const kc::ReducedDynamics reduced(*l.model, l.forces, 0.0);
  p.z0 = reduced.initial().z[0];
  p.zd0 = reduced.initial().zd[0];
  l.problem = p;
  return l;
}

// theta'' = -w2 cos(theta) from (theta0, theta'0) at t, in closed form: with phi = theta +
// pi/2 a pendulum phi'' = -w2 sin(phi), oscillating (energy below the top), so
// sin(phi/2) = k sn(w t + u0, k).
struct ZState {
  long double z, zd;
};
ZState reduced_closed_form(long double th0, long double thd0, long double w2, long double t) {
  using std::asin, std::cos, std::sin, std::sqrt;
  const long double pi = 3.141592653589793238462643383279503L, w = sqrt(w2);
  const long double phi0 = th0 + pi / 2;
  const long double h = thd0 * thd0 / 2 - w2 * cos(phi0);
  const long double k = sqrt((h + w2) / (2 * w2));
  if (!(k < 1)) throw std::runtime_error("closed form: the motion is not an oscillation");
  const long double big_k = boost::math::ellint_1(k);
  const long double s0 = std::min(1.0L, std::max(-1.0L, sin(phi0 / 2) / k));
  long double u0 = boost::math::ellint_1(k, asin(s0));
  if (thd0 < 0) u0 = 2 * big_k - u0;
  long double cn = 0, dn = 0;
  const long double sn = boost::math::jacobi_elliptic(k, w * t + u0, &cn, &dn);
  const long double phi = 2 * asin(k * sn);
  return {phi - pi / 2, 2 * k * w * cn * dn / cos(phi / 2)};
}

// The reduced model's w^2 = G / I: the pendulum's m g a / (m (2a)^2 / 3); the N-four-bar's
// g m l (3N + 1) / 2 over (N + 1) m l^2 / 3 + N m l^2 (cranks turning, couplers translating).
long double reduced_w2(const kd::Problem& p) {
  if (p.name == "pendulum") return 3 * p.param("g") / (4 * p.param("a"));
  const long double n = p.n, m = p.param("m"), l = p.param("l");
  return p.param("g") * m * l * (3 * n + 1) / 2 / ((n + 1) * m * l * l / 3 + n * m * l * l);
}

std::vector<kd::Run> run_kinegen(const Loaded& l, kc::Method method,
                                 const std::vector<double>& tolerances, int repetitions) {
  std::vector<kd::Run> out;
  for (double tol : tolerances) {
    kd::Run run;
    run.method = method == kc::Method::kMinimal ? "kinegen minimal" : "kinegen augmented";
    char label[32];
    std::snprintf(label, sizeof label, "rtol=%.0e", tol);
    run.setting = label;
    kc::SimulateOptions o;
    o.rtol = tol;
    o.atol = tol;
    o.method = method;
    run.seconds = kd::best_seconds(repetitions, [&] {
      try {
        kc::run_simulation(*l.model, l.forces, {0, l.problem.t1, 1},
                           [&](const kc::SimulatedRow& r) {
                             run.z = r.z[0];
                             run.zd = r.zd[0];
                           },
                           o);
        return true;
      } catch (const std::exception& e) {
        run.ok = false;
        const std::string what = e.what();
        run.note = what.substr(0, std::min<std::size_t>(what.size(), 160));
        return false;
      }
    });
    out.push_back(run);
    if (!run.ok) break;  // the same failure at every tolerance
  }
  return out;
}

std::vector<kd::Run> run_generic(const Loaded& l, const std::vector<double>& tolerances,
                                 int repetitions) {
  std::vector<kd::Run> out;
  kd::GenericDae dae(*l.model, l.forces);
  for (double tol : tolerances) {
    kd::Run run;
    run.method = "generic DAE (IDA)";
    char label[32];
    std::snprintf(label, sizeof label, "rtol=%.0e", tol);
    run.setting = label;
    run.seconds = kd::best_seconds(repetitions, [&] {
      const kd::IdaResult r = kd::run_ida(dae, l.problem.t1, tol);
      run.z = r.z;
      run.zd = r.zd;
      run.steps = r.steps;
      if (!r.failure.empty()) {
        run.ok = false;
        run.note = r.failure;
        return false;
      }
      return true;
    });
    out.push_back(run);
  }
  return out;
}

struct Table {
  std::ofstream csv;
  void problem_header(const kd::Problem& p, const ZState& ref, const std::string& how) {
    std::printf("\n== %s: reference z(t1) = %.15Lg, zd(t1) = %.15Lg (%s)\n", p.label.c_str(),
                ref.z, ref.zd, how.c_str());
    std::printf("  %-22s %-10s %12s %12s %12s %9s  %s\n", "method", "setting", "seconds",
                "error z", "error zd", "steps", "note");
  }
  void row(const kd::Problem& p, const kd::Run& r, const ZState& ref, double zd_scale) {
    const double ez = std::abs(r.z - static_cast<double>(ref.z));
    const double ezd = std::abs(r.zd - static_cast<double>(ref.zd)) / zd_scale;
    std::printf("  %-22s %-10s %12.4e %12.3e %12.3e %9ld  %s\n", r.method.c_str(),
                r.setting.c_str(), r.seconds, r.ok ? ez : NAN, r.ok ? ezd : NAN, r.steps,
                r.note.c_str());
    std::string note = r.note;
    for (char& ch : note)
      if (ch == ',' || ch == '\n') ch = ';';
    std::string label = p.label;
    for (char& ch : label)
      if (ch == ',') ch = ';';
    csv << label << "," << r.method << "," << r.setting << "," << r.seconds << ","
        << (r.ok ? ez : NAN) << "," << (r.ok ? ezd : NAN) << "," << r.steps << "," << r.ok
        << "," << note << "\n";
  }
};

// The generated dynamics() against each other method at equal error of z, measured in this
// run: for each of the method's runs (time T at error e), T over the generated runs' time at
// e, that time log-log interpolated between two runs of one generated line (RK4 or CVODE)
// whose errors bracket e, or the cheapest generated run with an error at most e (whichever
// is less); no extrapolation, so a run more accurate than every generated one has no ratio.
// Conservatively (in brackets): the cheapest generated run with an error at most e.
void print_ratios(const std::vector<kd::Run>& runs, const ZState& ref) {
  const auto error = [&](const kd::Run& r) { return std::abs(r.z - static_cast<double>(ref.z)); };
  const auto generated = [](const kd::Run& r) { return r.method.rfind("generated", 0) == 0; };
  const auto generated_time = [&](double e, bool interpolate) {
    double best = INFINITY;
    for (const kd::Run& g : runs)
      if (generated(g) && g.ok && error(g) <= e) best = std::min(best, g.seconds);
    if (!interpolate) return best;
    for (std::size_t k = 0; k + 1 < runs.size(); ++k) {
      const kd::Run &a = runs[k], &b = runs[k + 1];
      if (!generated(a) || a.method != b.method || !a.ok || !b.ok) continue;
      const double ea = error(a), eb = error(b);
      if (!(ea > e && e >= eb)) continue;
      const double f = std::log(e / ea) / std::log(eb / ea);
      best = std::min(best, std::exp(std::log(a.seconds) + f * std::log(b.seconds / a.seconds)));
    }
    return best;
  };
  std::printf("  ratios at equal error of z, the method's time over the generated dynamics()' "
              "(interpolated; [the cheapest generated run at most as inaccurate]):\n");
  std::vector<std::string> methods;
  for (const kd::Run& r : runs)
    if (!generated(r) && std::find(methods.begin(), methods.end(), r.method) == methods.end())
      methods.push_back(r.method);
  for (const std::string& m : methods) {
    std::string line;
    for (const kd::Run& r : runs) {
      if (r.method != m || !r.ok) continue;
      const double e = error(r), t = generated_time(e, true), c = generated_time(e, false);
      char cell[96];
      if (std::isfinite(t))
        std::snprintf(cell, sizeof cell, " %.1e: %.0fx [%.0fx];", e, r.seconds / t,
                      std::isfinite(c) ? r.seconds / c : NAN);
      else
        std::snprintf(cell, sizeof cell, " %.1e: -;", e);
      line += cell;
    }
    std::printf("    %-20s%s\n", m.c_str(), line.empty() ? " no run reached t1" : line.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string csv_path = "bench_dynamics.csv";
  bool quick = false;
  for (int k = 1; k < argc; ++k) {
    const std::string a = argv[k];
    if (a == "--quick") quick = true;
    else csv_path = a;
  }
  const std::string dir = std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/";
  const std::filesystem::path nfb =
      std::filesystem::temp_directory_path() / "kinegen_bench_n_four_bar_40.yaml";
  std::ofstream(nfb) << n_four_bar_yaml(40);

  std::vector<double> tolerances = kd::kTolerances;
  if (quick) tolerances = {1e-4, 1e-8};
  // The generated RK4's step sizes (rounded to t1 / n).
  std::vector<double> steps = {1e-2, 3e-3, 1e-3, 3e-4, 1e-4};
  if (quick) steps = {1e-2, 1e-3};
  const int reps = quick ? 1 : 3;

  std::vector<Loaded> problems;
  {
    kd::Problem p;
    p.name = p.label = "pendulum";
    p.label = "pendulum, t1 = 10";
    p.t1 = 10;
    problems.push_back(load(dir + "pendulum.yaml", p));
  }
  {
    kd::Problem p;
    p.name = "press_flywheel";
    p.label = "press_flywheel, t1 = 3";
    p.t1 = 3;
    problems.push_back(load(dir + "press_flywheel.yaml", p));
  }
  // The N-four-bar: up to 90% of the time of its first flat position (where the minimal
  // coordinates stop), and over the benchmark's 20 s through both flat positions.
  double t_flat = 0;
  {
    kd::Problem p;
    p.name = "n_four_bar";
    p.n = 40;
    p.t1 = 1;
    Loaded l = load(nfb.string(), p);
    const long double w2 = reduced_w2(l.problem);
    double lo = 0, hi = 1;  // theta falls from pi/4 through 0 within the first second
    for (int it = 0; it < 100; ++it) {
      const double mid = (lo + hi) / 2;
      (reduced_closed_form(l.problem.z0, l.problem.zd0, w2, mid).z > 0 ? lo : hi) = mid;
    }
    t_flat = lo;
    l.problem.t1 = 0.9 * t_flat;
    char label[96];
    std::snprintf(label, sizeof label, "n_four_bar N=40, t1 = %.4f (0.9 x first flat position)",
                  l.problem.t1);
    l.problem.label = label;
    problems.push_back(std::move(l));
    if (!quick) {
      Loaded full = load(nfb.string(), p);
      full.problem.t1 = 20;
      full.problem.label = "n_four_bar N=40, t1 = 20 (A02: both flat positions)";
      problems.push_back(std::move(full));
    }
  }

  Table table;
  table.csv.open(csv_path);
  table.csv << "problem,method,setting,seconds,error_z,error_zd,steps,ok,note\n";
  std::printf("Dynamics work-precision: run time (s, best of up to %d) against the error at "
              "t1\nof the free coordinate z (rad) and of its rate (relative to max |zd| of "
              "the reference).\n",
              reps);
  for (const Loaded& l : problems) {
    const kd::Problem& p = l.problem;
    const bool full = p.t1 > 10 && p.name == "n_four_bar";
    const std::vector<double> tols = full ? std::vector<double>{1e-4, 1e-6} : tolerances;
    // The reference and the scale of the rate.
    ZState ref{};
    std::string how;
    double zd_scale = std::abs(p.zd0);
    if (p.name == "press_flywheel") {
      kc::SimulateOptions o;
      o.rtol = o.atol = 1e-13;
      kc::run_simulation(*l.model, l.forces, {0, p.t1, 300},
                         [&](const kc::SimulatedRow& r) {
                           ref = {r.z[0], r.zd[0]};
                           zd_scale = std::max(zd_scale, std::abs(r.zd[0]));
                         },
                         o);
      how = "kinegen simulate at rtol 1e-13";
    } else {
      const long double w2 = reduced_w2(p);
      ref = reduced_closed_form(p.z0, p.zd0, w2, p.t1);
      for (int k = 0; k <= 1000; ++k)
        zd_scale = std::max(zd_scale, static_cast<double>(std::abs(
                                          reduced_closed_form(p.z0, p.zd0, w2, p.t1 * k / 1000)
                                              .zd)));
      how = "closed form of the reduced model, Jacobi elliptic functions";
    }
    table.problem_header(p, ref, how);
    std::vector<kd::Run> runs = run_kinegen(l, kc::Method::kMinimal, tols, reps);
    if (p.name == "n_four_bar") {
      auto aug = run_kinegen(l, kc::Method::kAugmented, tols, reps);
      runs.insert(runs.end(), aug.begin(), aug.end());
    }
    std::string skipped;
    auto generated = kd::run_generated(p, tols, full ? std::vector<double>{1e-3} : steps, reps,
                                       skipped);
    if (!skipped.empty()) std::printf("  %s\n", skipped.c_str());
    runs.insert(runs.end(), generated.begin(), generated.end());
    skipped.clear();
    auto simbody = kd::run_simbody(p, tols, reps, skipped);
    if (!skipped.empty()) std::printf("  %s\n", skipped.c_str());
    runs.insert(runs.end(), simbody.begin(), simbody.end());
    auto generic = run_generic(l, tols, reps);
    runs.insert(runs.end(), generic.begin(), generic.end());
    for (const kd::Run& r : runs) table.row(p, r, ref, zd_scale);
    print_ratios(runs, ref);
    std::fflush(stdout);
  }
  std::filesystem::remove(nfb);
  std::printf("\nwrote %s\n", csv_path.c_str());
  return 0;
}
