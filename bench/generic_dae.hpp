// The generic formulation a user writes without kinegen, for the dynamics benchmark: the full
// Cartesian index-1 DAE of Haug's equations of motion in all coordinates,
//   q' = v,   M(q) v' + Phi_q^T lambda = Q^A(q, v, t) + Q_v(q, v),
//   Phi_q v' = gamma(q, v) - 2 alpha Phi_q v - beta^2 Phi(q)      (Baumgarte's stabilization),
// solved by SUNDIALS IDA (BDF, variable order and step) with its dense linear solver and
// difference-quotient Jacobian, lambda algebraic. The mechanism comes from the same file:
// Phi, Phi_q and gamma from the generic joint library (generic_solver.hpp: loops over joint
// records of numbers, Haug's formulas), Q^A from the loads' program run by the interpreter,
// M and the quadratic velocity terms Q_v from each body's mass, inertia and centre of mass
// (add_inertia_forces). The consistent start (q, v at t0) is kinegen's assembly; v' and
// lambda at t0 solve the augmented system once.
#pragma once

#include <ida/ida.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <Eigen/Dense>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "generic_from_mechanism.hpp"
#include "kinegen/codegen/analysis/dynamics.hpp"
#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/analysis/forces.hpp"

namespace kinegen::bench::dynamics {

class GenericDae {
 public:
  // alpha, beta: Baumgarte's gains [1/s].
  GenericDae(const codegen::CompiledModel& model, const codegen::ForceModel& forces,
             double alpha = 5, double beta = 5)
      : model_(model),
        forces_(forces),
        applied_program_(codegen::lower(forces.applied, model.symbols())),
        applied_(applied_program_),
        alpha_(alpha),
        beta_(beta) {
    std::string why;
    auto data = generic::from_compiled_model(model, why, /*skip_free=*/true);
    if (!data) throw std::runtime_error("generic DAE: " + why);
    system_.emplace(*data);
    nq_ = system_->nq();
    nc_ = system_->nc();
    jac_.setZero(nc_, nq_);
    // The consistent start: kinegen's assembly at t0 (value0, v0 of the free item).
    const codegen::ReducedDynamics reduced(model, forces, 0.0);
    q0_ = reduced.initial().q;
    v0_ = reduced.initial().qd;
    free_body_ = model.mechanism().drivers[model.mechanism().free_drivers()[0]].i;
  }

  int size() const { return 2 * nq_ + nc_; }

  // The residual F(t, y, y') at y = [q, v, lambda].
  void residual(double t, const double* y, const double* yp, double* f) {
    const double *q = y, *v = y + nq_, *lambda = y + 2 * nq_, *vp = yp + nq_;
    for (int k = 0; k < nq_; ++k) f[k] = yp[k] - v[k];
    jac_.setZero();
    system_->jacobian(q, t, jac_);
    // Phi_q^T lambda - Q^A - (inertia forces of v' and v: -M v' - Q_v).
    Eigen::Map<Eigen::VectorXd> f2(f + nq_, nq_);
    work_.assign(nq_, 0.0);
    applied_.run(q, v, t, model_.params().data(), work_.data());
    codegen::add_inertia_forces(forces_.numbers, nq_ / 3, q, v, vp, work_.data());
    f2 = jac_.transpose() * Eigen::Map<const Eigen::VectorXd>(lambda, nc_) -
         Eigen::Map<const Eigen::VectorXd>(work_.data(), nq_);
    // Phi_q v' - gamma + 2 alpha Phi_q v + beta^2 Phi.
    Eigen::Map<Eigen::VectorXd> f3(f + 2 * nq_, nc_);
    gamma_.resize(nc_);
    phi_.resize(nc_);
    system_->gamma(q, v, t, gamma_.data());
    system_->phi(q, t, phi_.data());
    const Eigen::Map<const Eigen::VectorXd> vv(v, nq_), vpv(vp, nq_);
    f3 = jac_ * vpv - gamma_ + 2 * alpha_ * (jac_ * vv) + beta_ * beta_ * phi_;
  }

  // y and y' at t0: q0, v0, then v' and lambda from [M Phi_q^T; Phi_q 0] [v'; lambda] =
  // [Q^A + Q_v; gamma].
  void initial(std::vector<double>& y, std::vector<double>& yp) {
    const int n = size();
    y.assign(n, 0.0);
    yp.assign(n, 0.0);
    for (int k = 0; k < nq_; ++k) {
      y[k] = q0_[k];
      y[nq_ + k] = v0_[k];
      yp[k] = v0_[k];
    }
    // With v' = 0 the residual is [.., -(Q^A + Q_v) + Phi_q^T lambda, -gamma + ...]: its
    // change with v' and lambda is the augmented matrix, which columns of unit v' give.
    Eigen::MatrixXd a(nq_ + nc_, nq_ + nc_);
    std::vector<double> f0(n), f1(n), yl = y, ypl = yp;
    residual(0, y.data(), yp.data(), f0.data());
    for (int c = 0; c < nq_ + nc_; ++c) {
      ypl = yp;
      yl = y;
      if (c < nq_) ypl[nq_ + c] = 1; else yl[2 * nq_ + (c - nq_)] = 1;
      residual(0, yl.data(), ypl.data(), f1.data());
      for (int r = 0; r < nq_ + nc_; ++r) a(r, c) = f1[nq_ + r] - f0[nq_ + r];
    }
    Eigen::VectorXd rhs(nq_ + nc_);
    for (int r = 0; r < nq_ + nc_; ++r) rhs[r] = -f0[nq_ + r];
    const Eigen::VectorXd x = a.partialPivLu().solve(rhs);
    for (int k = 0; k < nq_; ++k) yp[nq_ + k] = x[k];
    for (int k = 0; k < nc_; ++k) y[2 * nq_ + k] = x[nq_ + k];
  }

  // The free coordinate (an absolute angle) and its rate in y.
  double z(const double* y) const { return y[3 * free_body_ + 2]; }
  double zd(const double* y) const { return y[nq_ + 3 * free_body_ + 2]; }
  double length_scale() const { return model_.symbolic().length_scale; }
  int nq() const { return nq_; }

 private:
  const codegen::CompiledModel& model_;
  const codegen::ForceModel& forces_;
  codegen::Program applied_program_;
  codegen::ProgramEvaluator<double> applied_;
  std::optional<generic::GenericSystem> system_;
  int nq_ = 0, nc_ = 0, free_body_ = 0;
  double alpha_, beta_;
  Eigen::MatrixXd jac_;
  Eigen::VectorXd gamma_, phi_, q0_, v0_;
  std::vector<double> work_;
};

// One IDA run of the generic DAE from t0 = 0 to t1 at rtol (atol: rtol times each entry's
// scale, the length scale for x and y, 1 for angles, lambda left out of the error test).
struct IdaResult {
  double z = NAN, zd = NAN;
  long steps = 0;
  std::string failure;
};

inline IdaResult run_ida(GenericDae& dae, double t1, double rtol) {
  IdaResult out;
  SUNContext ctx = nullptr;
  if (SUNContext_Create(nullptr, &ctx) != 0) throw std::runtime_error("SUNContext_Create");
  const int n = dae.size(), nq = dae.nq();
  N_Vector y = N_VNew_Serial(n, ctx), yp = N_VNew_Serial(n, ctx), atol = N_VNew_Serial(n, ctx),
           id = N_VNew_Serial(n, ctx);
  std::vector<double> y0, yp0;
  dae.initial(y0, yp0);
  for (int k = 0; k < n; ++k) {
    NV_Ith_S(y, k) = y0[k];
    NV_Ith_S(yp, k) = yp0[k];
    const bool angle = k < 2 * nq && (k % nq) % 3 == 2;
    NV_Ith_S(atol, k) = rtol * (angle ? 1.0 : dae.length_scale());
    NV_Ith_S(id, k) = k < 2 * nq ? 1.0 : 0.0;
  }
  void* mem = IDACreate(ctx);
  auto res = [](double t, N_Vector yy, N_Vector yyp, N_Vector rr, void* data) {
    static_cast<GenericDae*>(data)->residual(t, N_VGetArrayPointer(yy), N_VGetArrayPointer(yyp),
                                             N_VGetArrayPointer(rr));
    return 0;
  };
  IDAInit(mem, res, 0.0, y, yp);
  IDASVtolerances(mem, rtol, atol);
  IDASetUserData(mem, &dae);
  IDASetId(mem, id);
  IDASetSuppressAlg(mem, SUNTRUE);
  IDASetMaxNumSteps(mem, 10000000);
  IDASetStopTime(mem, t1);
  IDASetErrHandlerFn(mem, [](int, const char*, const char*, char*, void*) {}, nullptr);
  SUNMatrix a = SUNDenseMatrix(n, n, ctx);
  SUNLinearSolver ls = SUNLinSol_Dense(y, a, ctx);
  IDASetLinearSolver(mem, ls, a);
  double reached = 0;
  const int flag = IDASolve(mem, t1, &reached, y, yp, IDA_NORMAL);
  if (flag < 0)
    out.failure = std::string("IDA: ") + IDAGetReturnFlagName(flag) + " at t = " +
                  std::to_string(reached);
  out.z = dae.z(N_VGetArrayPointer(y));
  out.zd = dae.zd(N_VGetArrayPointer(y));
  IDAGetNumSteps(mem, &out.steps);
  IDAFree(&mem);
  SUNLinSolFree(ls);
  SUNMatDestroy(a);
  for (N_Vector v : {y, yp, atol, id}) N_VDestroy(v);
  SUNContext_Free(&ctx);
  return out;
}

}  // namespace kinegen::bench::dynamics
