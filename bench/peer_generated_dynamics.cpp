// The generated dynamics() as a peer of the dynamics work-precision benchmark
// (bench_dynamics.cpp): the committed headers generated/pendulum.hpp, press_flywheel.hpp and
// n_four_bar_40.hpp, stepped (a) by the header's fixed-step step_rk4() and (b) by SUNDIALS
// CVODE's C API on y = (z, zd), y' = (zd, zdd) with zdd from dynamics(), in the settings
// `kinegen simulate` uses (codegen/src/analysis/simulate.cpp): Adams with the fixed-point
// solver (no springs or dampers in these models; the library takes BDF only with them or with
// its augmented projection), atol = tol times each state's scale, rtol = tol, at most 1e7
// steps, 20 error-test failures, a stop time at t1 and a smallest step of 1e-12 t1. The one
// difference: the library integrates the work of the loads as one more state (its energy
// check); that state is not here.
// Compiled on its own as C++17, like the Simbody peer: the headers and CVODE only.
#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "dynamics_peers.hpp"
#include "n_four_bar_40.hpp"
#include "pendulum.hpp"
#include "press_flywheel.hpp"

namespace kinegen::bench::dynamics {

namespace {

std::string label(const char* what, double value) {
  char s[32];
  std::snprintf(s, sizeof s, "%s=%.0e", what, value);
  return s;
}

std::string failure(const char* where, int status, double t) {
  char s[160];
  std::snprintf(s, sizeof s,
                "%s: dynamics() status %d at t = %.6g (the minimal coordinates stop at the "
                "singular position; the augmented method passes it)",
                where, status, t);
  return s;
}

// The header's RK4 from (z0, zd0) at t = 0 to t1 in n = round(t1 / h) equal steps.
template <class M>
std::vector<Run> run_rk4(const Problem& p, const std::vector<double>& steps, int repetitions) {
  static_assert(M::nf == 1, "the benchmark's problems have one free coordinate");
  std::vector<Run> out;
  const typename M::Params params;  // the file's values, as the other peers use
  const typename M::BlockOptions options;
  typename M::template DynamicsWork<double> w;
  for (double h0 : steps) {
    Run run;
    run.method = "generated RK4";
    run.setting = label("h", h0);
    const long n = std::max(1L, std::lround(p.t1 / h0));
    const double h = p.t1 / n;
    run.steps = n;
    run.seconds = best_seconds(repetitions, [&] {
      w.reset();  // a new start: the file's q0, no branch recorded
      double z = p.z0, zd = p.zd0, t = 0;
      for (long k = 0; k < n; ++k) {
        const auto r = M::step_rk4(&z, &zd, t, h, params, options, w);
        if (r.status != 0) {
          run.ok = false;
          run.note = failure("RK4", r.status, t);
          return false;
        }
      }
      run.z = z;
      run.zd = zd;
      return true;
    });
    out.push_back(run);
    if (!run.ok) break;  // a singular position: every step size reaches it
  }
  return out;
}

template <class M>
struct CvodeData {
  typename M::Params params;
  typename M::BlockOptions options;
  typename M::template DynamicsWork<double> w;
  int status = 0;  // the last failed dynamics()'s
  double t = 0;
};

template <class M>
int rhs(double t, N_Vector y, N_Vector ydot, void* user) {
  auto* d = static_cast<CvodeData<M>*>(user);
  const double* yv = N_VGetArrayPointer(y);
  double* dv = N_VGetArrayPointer(ydot);
  dv[0] = yv[1];
  const auto r = M::dynamics(yv, yv + 1, t, d->params, dv + 1, d->options, d->w);
  if (r.status != 0) {
    d->status = r.status;
    d->t = t;
    return 1;  // recoverable, as the library's: CVODE retries with a smaller step
  }
  d->status = 0;
  return 0;
}

void quiet(int, const char*, const char*, char*, void*) {}

template <class M>
std::vector<Run> run_cvode(const Problem& p, const std::vector<double>& tolerances,
                           int repetitions) {
  std::vector<Run> out;
  CvodeData<M> data;
  for (double tol : tolerances) {
    Run run;
    run.method = "generated CVODE";
    run.setting = label("rtol", tol);
    run.seconds = best_seconds(repetitions, [&] {
      // The set-up is timed, as the library's run_simulation sets up its own.
      data.w.reset();
      data.status = 0;
      SUNContext ctx = nullptr;
      if (SUNContext_Create(nullptr, &ctx) != 0) return false;
      N_Vector y = N_VNew_Serial(2, ctx), atol = N_VNew_Serial(2, ctx);
      NV_Ith_S(y, 0) = p.z0;
      NV_Ith_S(y, 1) = p.zd0;
      // The free coordinate is an angle in every problem: scale 1 (a length's would be the
      // header's length_scale).
      NV_Ith_S(atol, 0) = NV_Ith_S(atol, 1) = tol;
      void* cvode = CVodeCreate(CV_ADAMS, ctx);
      SUNNonlinearSolver nls = SUNNonlinSol_FixedPoint(y, 0, ctx);
      CVodeSetErrHandlerFn(cvode, &quiet, nullptr);
      CVodeInit(cvode, &rhs<M>, 0.0, y);
      CVodeSVtolerances(cvode, tol, atol);
      CVodeSetUserData(cvode, &data);
      CVodeSetMaxNumSteps(cvode, 10000000);
      CVodeSetMaxErrTestFails(cvode, 20);
      CVodeSetNonlinearSolver(cvode, nls);
      CVodeSetStopTime(cvode, p.t1);
      CVodeSetMinStep(cvode, 1e-12 * p.t1);
      double reached = 0;
      const int flag = CVode(cvode, p.t1, y, &reached, CV_NORMAL);
      long steps = 0;
      CVodeGetNumSteps(cvode, &steps);
      run.steps = steps;
      run.z = NV_Ith_S(y, 0);
      run.zd = NV_Ith_S(y, 1);
      if (flag < 0) {
        run.ok = false;
        run.note = data.status != 0 ? failure("CVODE", data.status, data.t)
                                    : std::string("CVODE: ") + CVodeGetReturnFlagName(flag);
      }
      CVodeFree(&cvode);
      SUNNonlinSolFree(nls);
      N_VDestroy(y);
      N_VDestroy(atol);
      SUNContext_Free(&ctx);
      return run.ok;
    });
    out.push_back(run);
    if (!run.ok) break;
  }
  return out;
}

template <class M>
std::vector<Run> run_model(const Problem& p, const std::vector<double>& tolerances,
                           const std::vector<double>& steps, int repetitions) {
  std::vector<Run> out = run_rk4<M>(p, steps, repetitions);
  const std::vector<Run> cvode = run_cvode<M>(p, tolerances, repetitions);
  out.insert(out.end(), cvode.begin(), cvode.end());
  return out;
}

}  // namespace

std::vector<Run> run_generated(const Problem& p, const std::vector<double>& tolerances,
                               const std::vector<double>& steps, int repetitions,
                               std::string& skipped) {
  if (p.name == "pendulum") return run_model<models::pendulum>(p, tolerances, steps, repetitions);
  if (p.name == "press_flywheel")
    return run_model<models::press_flywheel>(p, tolerances, steps, repetitions);
  if (p.name == "n_four_bar" && p.n == 40)
    return run_model<models::n_four_bar_40>(p, tolerances, steps, repetitions);
  skipped = "generated dynamics(): no committed header for " + p.name;
  return {};
}

}  // namespace kinegen::bench::dynamics
